"""Typed exceptions. Each carries the stable code of the API's problem document
(`command.busy`, `kernel.estop`, `lease.held`, ...), the HTTP status and the document."""

from __future__ import annotations

from typing import Any


class RtcncError(Exception):
    """An error answer of the API (an RFC 9457 problem document)."""

    def __init__(self, code: str, detail: str, status: int = 0, problem: dict[str, Any] | None = None):
        super().__init__(f"{code}: {detail}")
        self.code = code
        self.detail = detail
        self.status = status
        self.problem = problem or {}

    @property
    def extra(self) -> dict[str, Any]:
        return self.problem.get("extra") or {}


class Unauthorized(RtcncError):
    """401: no session, or it expired."""


class Forbidden(RtcncError):
    """403: the role does not allow it (or the one-time password must be changed)."""


class NotFound(RtcncError):
    """404."""


class Conflict(RtcncError):
    """409: the machine's state refuses the command, or another session holds the lease."""


class LeaseRequired(Conflict):
    """409 with `lease.required` or `lease.held`."""


class Unprocessable(RtcncError):
    """422: a bad value, or a program with errors (`extra["errors"]`)."""


class RateLimited(RtcncError):
    """429: too many failed log-ins."""


class MachineUnavailable(RtcncError):
    """503: the machine process is gone; the API attaches again when it is back."""


class CommandRefused(RtcncError):
    """The kernel refused a command, or what it started failed."""


class CommandTimeout(RtcncError):
    """A command was not done within the time asked."""


_BY_STATUS = {
    401: Unauthorized,
    403: Forbidden,
    404: NotFound,
    409: Conflict,
    422: Unprocessable,
    429: RateLimited,
    503: MachineUnavailable,
}


def from_problem(status: int, problem: dict[str, Any]) -> RtcncError:
    code = str(problem.get("code", f"http.{status}"))
    detail = str(problem.get("detail", ""))
    cls = _BY_STATUS.get(status, RtcncError)
    if status == 409 and code.startswith("lease."):
        cls = LeaseRequired
    elif status == 409 and code.startswith("command."):
        cls = CommandRefused
    return cls(code, detail, status, problem)
