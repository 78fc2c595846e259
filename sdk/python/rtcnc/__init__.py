"""Python client of the rtcnc API: `Client` (blocking), `AsyncClient` (asyncio, with the
WebSocket as `subscribe()`), models generated from the OpenAPI document, typed exceptions
that carry the API's stable error codes."""

from . import models
from .client import Acknowledgement, AsyncAcknowledgement, AsyncClient, Client, Message
from .errors import (
    CommandRefused,
    CommandTimeout,
    Conflict,
    Forbidden,
    LeaseRequired,
    MachineUnavailable,
    NotFound,
    RateLimited,
    RtcncError,
    Unauthorized,
    Unprocessable,
)

__all__ = [
    "Acknowledgement",
    "AsyncAcknowledgement",
    "AsyncClient",
    "Client",
    "CommandRefused",
    "CommandTimeout",
    "Conflict",
    "Forbidden",
    "LeaseRequired",
    "MachineUnavailable",
    "Message",
    "NotFound",
    "RateLimited",
    "RtcncError",
    "Unauthorized",
    "Unprocessable",
    "models",
]
