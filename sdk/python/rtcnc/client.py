"""`Client` (blocking) and `AsyncClient` (asyncio) for the rtcnc API."""

from __future__ import annotations

import asyncio
import json
import ssl
from collections.abc import AsyncIterator
from dataclasses import dataclass, field
from typing import Any

import httpx
import websockets

from . import models
from .errors import CommandRefused, CommandTimeout, from_problem


def _raise_for(response: httpx.Response) -> None:
    if response.status_code < 400:
        return
    try:
        problem = response.json()
    except ValueError:
        problem = {"code": f"http.{response.status_code}", "detail": response.text}
    raise from_problem(response.status_code, problem)


def _ack_result(ack: models.Ack) -> models.Ack:
    if ack.state in ("refused", "failed"):
        raise CommandRefused(ack.code or "command.refused", ack.message or ack.state, 409, ack.model_dump())
    return ack


class Acknowledgement:
    """A command as the kernel took it; `.wait(timeout)` waits until what it started is done
    (raises `CommandRefused` when it was refused or failed, `CommandTimeout` on time-out)."""

    def __init__(self, client: Client, ack: models.Ack):
        self._client = client
        self.ack = ack

    @property
    def serial(self) -> int:
        return self.ack.serial

    @property
    def state(self) -> str:
        return self.ack.state

    def wait(self, timeout: float = 30.0) -> models.Ack:
        if self.ack.state in ("done", "refused", "failed"):
            return _ack_result(self.ack)
        self.ack = self._client.command_ack(self.serial, until="done", timeout=timeout)
        if self.ack.state not in ("done", "refused", "failed"):
            raise CommandTimeout("command.timeout", f"command {self.serial} not done within {timeout} s")
        return _ack_result(self.ack)

    def __repr__(self) -> str:
        return f"Acknowledgement(serial={self.serial}, state={self.state!r})"


class AsyncAcknowledgement:
    """The asyncio form of `Acknowledgement`: `await ack.wait(timeout)`."""

    def __init__(self, client: AsyncClient, ack: models.Ack):
        self._client = client
        self.ack = ack

    @property
    def serial(self) -> int:
        return self.ack.serial

    @property
    def state(self) -> str:
        return self.ack.state

    async def wait(self, timeout: float = 30.0) -> models.Ack:
        if self.ack.state in ("done", "refused", "failed"):
            return _ack_result(self.ack)
        self.ack = await self._client.command_ack(self.serial, until="done", timeout=timeout)
        if self.ack.state not in ("done", "refused", "failed"):
            raise CommandTimeout("command.timeout", f"command {self.serial} not done within {timeout} s")
        return _ack_result(self.ack)


def _jog_body(axis: str, velocity: float | None, distance: float | None) -> dict[str, Any]:
    body: dict[str, Any] = {"axis": axis}
    if velocity is not None:
        body["velocity"] = velocity
    if distance is not None:
        body["distance"] = distance
    return body


class Client:
    """A blocking client. `Client(url)`, then `login(user, password)` (or pass `token=`)."""

    def __init__(self, base_url: str, token: str | None = None, verify: bool | str | ssl.SSLContext = True,
                 timeout: float = 30.0):
        self.base_url = base_url.rstrip("/")
        self.token = token
        self._http = httpx.Client(base_url=self.base_url, verify=verify, timeout=timeout)

    def close(self) -> None:
        self._http.close()

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _headers(self) -> dict[str, str]:
        return {"Authorization": f"Bearer {self.token}"} if self.token else {}

    def _request(self, method: str, path: str, headers: dict[str, str] | None = None,
                 **kwargs: Any) -> httpx.Response:
        r = self._http.request(method, path, headers={**self._headers(), **(headers or {})}, **kwargs)
        _raise_for(r)
        return r

    def _command(self, path: str, body: dict[str, Any] | None = None) -> Acknowledgement:
        r = self._request("POST", path, json=body if body is not None else {})
        return Acknowledgement(self, models.Ack.model_validate(r.json()))

    # Session and lease.
    def login(self, user: str, password: str) -> models.SessionInfo:
        r = self._request("POST", "/api/session", json={"user": user, "password": password})
        info = models.SessionInfo.model_validate(r.json())
        self.token = info.token
        return info

    def logout(self) -> None:
        self._request("DELETE", "/api/session")
        self.token = None

    def session(self) -> models.SessionInfo:
        return models.SessionInfo.model_validate(self._request("GET", "/api/session").json())

    def change_password(self, old: str, new: str) -> None:
        self._request("POST", "/api/session/password", json={"old": old, "new": new})

    def acquire_lease(self, take_over: bool = False) -> models.Lease:
        params = {"take_over": "true"} if take_over else None
        return models.Lease.model_validate(self._request("POST", "/api/lease", params=params).json())

    def release_lease(self) -> None:
        self._request("DELETE", "/api/lease")

    def lease(self) -> models.Lease:
        return models.Lease.model_validate(self._request("GET", "/api/lease").json())

    # Status and events.
    def info(self) -> models.ApiInfo:
        return models.ApiInfo.model_validate(self._request("GET", "/api").json())

    def status(self) -> models.Status:
        return models.Status.model_validate(self._request("GET", "/api/status").json())

    def events(self, since: int = 0, limit: int = 1000) -> models.EventPage:
        r = self._request("GET", "/api/events", params={"since": since, "limit": limit})
        return models.EventPage.model_validate(r.json())

    def command_ack(self, serial: int, until: str = "accepted", timeout: float = 0.0) -> models.Ack:
        params = {"until": until, "timeout_ms": int(timeout * 1000)}
        r = self._http.request("GET", f"/api/commands/{serial}", params=params, headers=self._headers(),
                               timeout=timeout + 10.0)
        _raise_for(r)
        return models.Ack.model_validate(r.json())

    # Control.
    def reset(self) -> Acknowledgement:
        return self._command("/api/control/reset")

    def estop(self) -> Acknowledgement:
        return self._command("/api/control/estop")

    def feed_hold(self) -> Acknowledgement:
        return self._command("/api/control/feed-hold")

    def resume(self) -> Acknowledgement:
        return self._command("/api/control/resume")

    def stop(self) -> Acknowledgement:
        return self._command("/api/control/stop")

    def load_program(self, name: str) -> Acknowledgement:
        return self._command("/api/control/program", {"name": name})

    def cycle_start(self, from_line: int = 0) -> Acknowledgement:
        return self._command("/api/control/cycle-start", {"from_line": from_line})

    def single_block(self, on: bool) -> Acknowledgement:
        return self._command("/api/control/single-block", {"on": on})

    def optional_stop(self, on: bool) -> Acknowledgement:
        return self._command("/api/control/optional-stop", {"on": on})

    def block_delete(self, on: bool) -> Acknowledgement:
        return self._command("/api/control/block-delete", {"on": on})

    def mdi(self, line: str) -> Acknowledgement:
        return self._command("/api/control/mdi", {"line": line})

    def jog(self, axis: str, velocity: float | None = None, distance: float | None = None) -> Acknowledgement:
        return self._command("/api/control/jog", _jog_body(axis, velocity, distance))

    def jog_keep_alive(self, axis: str) -> None:
        self._request("POST", "/api/control/jog/keep-alive", json={"axis": axis})

    def jog_stop(self, axis: str) -> Acknowledgement:
        return self._command("/api/control/jog/stop", {"axis": axis})

    def home(self, axis: str | None = None) -> Acknowledgement:
        """Homes every joint in sequence, or only the joints of `axis`."""
        if axis is None:
            return self._command("/api/control/home")
        return self._command(f"/api/control/home/{axis}")

    def set_mode(self, mode: str) -> Acknowledgement:
        """Switches to "manual", "auto" or "mdi" (the machine must be idle)."""
        return self._command("/api/control/mode", {"mode": mode})

    def handwheel(self, axis: str | None, scale: float = 1.0) -> Acknowledgement:
        """Puts the handwheel on `axis` (×`scale` of the machine's units per count), or
        releases it with `axis=None`."""
        return self._command("/api/control/handwheel", {"axis": axis, "scale": scale})

    def set_overrides(self, feed: float | None = None, rapid: float | None = None,
                      spindle: float | None = None) -> list[models.Ack]:
        body = {k: v for k, v in (("feed", feed), ("rapid", rapid), ("spindle", spindle)) if v is not None}
        r = self._request("POST", "/api/control/overrides", json=body)
        return [models.Ack.model_validate(a) for a in r.json()]

    def spindle(self, direction: str, rpm: float | None = None) -> Acknowledgement:
        return self._command("/api/control/spindle", {"direction": direction, "rpm": rpm})

    def coolant(self, mist: bool = False, flood: bool = False) -> Acknowledgement:
        return self._command("/api/control/coolant", {"mist": mist, "flood": flood})

    # Programs.
    def programs(self) -> list[models.ProgramInfo]:
        return [models.ProgramInfo.model_validate(p) for p in self._request("GET", "/api/programs").json()]

    def upload_program(self, name: str, text: str | bytes) -> models.ProgramInfo:
        data = text.encode() if isinstance(text, str) else text
        r = self._request("PUT", f"/api/programs/{name}", content=data,
                          headers={"content-type": "text/plain"})
        return models.ProgramInfo.model_validate(r.json())

    def read_program(self, name: str) -> str:
        return self._request("GET", f"/api/programs/{name}").text

    def delete_program(self, name: str) -> None:
        self._request("DELETE", f"/api/programs/{name}")

    def preview(self, name: str) -> models.Preview:
        return models.Preview.model_validate(self._request("GET", f"/api/programs/{name}/preview").json())

    def estimate(self, name: str) -> models.Estimate:
        return models.Estimate.model_validate(self._request("GET", f"/api/programs/{name}/estimate").json())

    def check_program(self, name: str, text: str | bytes) -> models.ProgramCheck:
        """The interpreter's errors in a text, nothing stored."""
        data = text.encode() if isinstance(text, str) else text
        r = self._request("POST", f"/api/programs/{name}/check", content=data,
                          headers={"content-type": "text/plain"})
        return models.ProgramCheck.model_validate(r.json())

    def preview_binary(self, name: str) -> bytes:
        """The preview as one chain of points (docs/hmi.md has the layout)."""
        return self._request("GET", f"/api/programs/{name}/preview", params={"format": "binary"}).content

    # Setup.
    def machine_file(self) -> models.MachineFile:
        return models.MachineFile.model_validate(self._request("GET", "/api/setup/machine").json())

    def set_machine_file(self, text: str) -> models.MachineFileSaved:
        """Admin: replaces the machine file (checked as at the machine's start)."""
        r = self._request("PUT", "/api/setup/machine", content=text.encode(),
                          headers={"content-type": "text/plain"})
        return models.MachineFileSaved.model_validate(r.json())

    def tools(self) -> list[models.Tool]:
        return [models.Tool.model_validate(t) for t in self._request("GET", "/api/setup/tools").json()]

    def set_tools(self, tools: list[models.Tool]) -> Acknowledgement:
        r = self._request("PUT", "/api/setup/tools", json=[t.model_dump(exclude_none=True) for t in tools])
        return Acknowledgement(self, models.Ack.model_validate(r.json()))

    def offsets(self) -> list[models.WorkOffset]:
        return [models.WorkOffset.model_validate(o) for o in self._request("GET", "/api/setup/offsets").json()]

    def set_offset(self, system: str, offset: dict[str, float], rotation: float = 0.0) -> models.Ack:
        body = {"system": system, "offset": offset, "rotation": rotation}
        r = self._request("PUT", f"/api/setup/offsets/{system}", json=body)
        return _ack_result(models.Ack.model_validate(r.json()))

    # PLC.
    def plc_variables(self) -> list[models.PlcVariableInfo]:
        return [models.PlcVariableInfo.model_validate(v) for v in self._request("GET", "/api/plc/variables").json()]

    def plc_read(self, path: str) -> str:
        return models.PlcVariable.model_validate(self._request("GET", f"/api/plc/variables/{path}").json()).value

    def plc_watch(self, paths: list[str]) -> None:
        self._request("PUT", "/api/plc/watch", json={"paths": paths})

    def plc_force(self, path: str, value: str) -> str:
        r = self._request("POST", "/api/plc/force", json={"path": path, "value": value})
        return models.PlcVariable.model_validate(r.json()).value

    def plc_unforce(self, path: str) -> None:
        self._request("DELETE", f"/api/plc/force/{path}")

    # Diagnostics.
    def faults(self) -> list[models.FaultRecord]:
        return [models.FaultRecord.model_validate(f) for f in self._request("GET", "/api/faults").json()]

    def acknowledge_faults(self, up_to_seq: int) -> list[models.FaultRecord]:
        r = self._request("POST", "/api/faults/acknowledge", json={"up_to_seq": up_to_seq})
        return [models.FaultRecord.model_validate(f) for f in r.json()]

    def timing(self) -> models.Timing:
        return models.Timing.model_validate(self._request("GET", "/api/diagnostics/timing").json())

    def trace(self) -> dict[str, Any]:
        return self._request("GET", "/api/diagnostics/trace").json()


@dataclass
class Message:
    """One WebSocket message: `type` (`snapshot`, `status`, `event`, `trace`, `heartbeat`,
    `events_lost`, ...), the raw document, and for `snapshot`/`status` the whole status with
    the changes applied, for `event` the event."""

    type: str
    raw: dict[str, Any]
    status: models.Status | None = None
    event: models.Event | None = None
    samples: list[dict[str, Any]] = field(default_factory=list)


class AsyncClient:
    """The asyncio client, with `subscribe()` for the WebSocket."""

    def __init__(self, base_url: str, token: str | None = None, verify: bool | str | ssl.SSLContext = True,
                 timeout: float = 30.0):
        self.base_url = base_url.rstrip("/")
        self.token = token
        self._verify = verify
        self._http = httpx.AsyncClient(base_url=self.base_url, verify=verify, timeout=timeout)

    async def aclose(self) -> None:
        await self._http.aclose()

    async def __aenter__(self) -> AsyncClient:
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.aclose()

    def _headers(self) -> dict[str, str]:
        return {"Authorization": f"Bearer {self.token}"} if self.token else {}

    async def _request(self, method: str, path: str, headers: dict[str, str] | None = None,
                       **kwargs: Any) -> httpx.Response:
        r = await self._http.request(method, path, headers={**self._headers(), **(headers or {})}, **kwargs)
        _raise_for(r)
        return r

    async def _command(self, path: str, body: dict[str, Any] | None = None) -> AsyncAcknowledgement:
        r = await self._request("POST", path, json=body if body is not None else {})
        return AsyncAcknowledgement(self, models.Ack.model_validate(r.json()))

    async def login(self, user: str, password: str) -> models.SessionInfo:
        r = await self._request("POST", "/api/session", json={"user": user, "password": password})
        info = models.SessionInfo.model_validate(r.json())
        self.token = info.token
        return info

    async def acquire_lease(self, take_over: bool = False) -> models.Lease:
        params = {"take_over": "true"} if take_over else None
        return models.Lease.model_validate((await self._request("POST", "/api/lease", params=params)).json())

    async def status(self) -> models.Status:
        return models.Status.model_validate((await self._request("GET", "/api/status")).json())

    async def events(self, since: int = 0, limit: int = 1000) -> models.EventPage:
        r = await self._request("GET", "/api/events", params={"since": since, "limit": limit})
        return models.EventPage.model_validate(r.json())

    async def command_ack(self, serial: int, until: str = "accepted", timeout: float = 0.0) -> models.Ack:
        params = {"until": until, "timeout_ms": int(timeout * 1000)}
        r = await self._http.request("GET", f"/api/commands/{serial}", params=params, headers=self._headers(),
                                     timeout=timeout + 10.0)
        _raise_for(r)
        return models.Ack.model_validate(r.json())

    async def reset(self) -> AsyncAcknowledgement:
        return await self._command("/api/control/reset")

    async def estop(self) -> AsyncAcknowledgement:
        return await self._command("/api/control/estop")

    async def feed_hold(self) -> AsyncAcknowledgement:
        return await self._command("/api/control/feed-hold")

    async def resume(self) -> AsyncAcknowledgement:
        return await self._command("/api/control/resume")

    async def stop(self) -> AsyncAcknowledgement:
        return await self._command("/api/control/stop")

    async def load_program(self, name: str) -> AsyncAcknowledgement:
        return await self._command("/api/control/program", {"name": name})

    async def cycle_start(self, from_line: int = 0) -> AsyncAcknowledgement:
        return await self._command("/api/control/cycle-start", {"from_line": from_line})

    async def mdi(self, line: str) -> AsyncAcknowledgement:
        return await self._command("/api/control/mdi", {"line": line})

    async def jog(self, axis: str, velocity: float | None = None,
                  distance: float | None = None) -> AsyncAcknowledgement:
        return await self._command("/api/control/jog", _jog_body(axis, velocity, distance))

    async def jog_stop(self, axis: str) -> AsyncAcknowledgement:
        return await self._command("/api/control/jog/stop", {"axis": axis})

    async def upload_program(self, name: str, text: str | bytes) -> models.ProgramInfo:
        data = text.encode() if isinstance(text, str) else text
        r = await self._request("PUT", f"/api/programs/{name}", content=data,
                                headers={"content-type": "text/plain"})
        return models.ProgramInfo.model_validate(r.json())

    def _ws_url(self) -> str:
        url = self.base_url.replace("https://", "wss://", 1).replace("http://", "ws://", 1)
        return f"{url}/api/ws?token={self.token}"

    async def subscribe(self, rate_hz: float = 10.0, events: bool = True, trace: bool = False,
                        trace_decimation: int = 10) -> AsyncIterator[Message]:
        """The WebSocket as an async iterator: a `snapshot` first, then `status` (the whole
        status, changes applied), `event`, `trace`, `heartbeat` messages."""
        ssl_context = None
        if self.base_url.startswith("https://"):
            ssl_context = self._verify if isinstance(self._verify, ssl.SSLContext) else ssl.create_default_context()
            if self._verify is False:
                ssl_context.check_hostname = False
                ssl_context.verify_mode = ssl.CERT_NONE
        async with websockets.connect(self._ws_url(), ssl=ssl_context, max_size=2**24) as ws:
            await ws.send(json.dumps({"type": "subscribe", "rate_hz": rate_hz, "events": events,
                                      "trace": trace, "trace_decimation": trace_decimation}))
            current: dict[str, Any] = {}
            async for text in ws:
                raw = json.loads(text)
                kind = raw.get("type", "")
                if kind == "snapshot":
                    current = raw["status"]
                    yield Message(kind, raw, status=models.Status.model_validate(current))
                elif kind == "status":
                    current = {**current, **raw["changes"]}
                    yield Message(kind, raw, status=models.Status.model_validate(current))
                elif kind == "event":
                    yield Message(kind, raw, event=models.Event.model_validate(raw["event"]))
                elif kind == "trace":
                    yield Message(kind, raw, samples=raw["samples"])
                else:
                    yield Message(kind, raw)

    async def keep_jogging(self, axis: str, seconds: float, period: float = 0.1) -> None:
        """Sends keep-alives for a continuous jog for `seconds`."""
        end = asyncio.get_running_loop().time() + seconds
        while asyncio.get_running_loop().time() < end:
            await self._request("POST", "/api/control/jog/keep-alive", json={"axis": axis})
            await asyncio.sleep(period)
