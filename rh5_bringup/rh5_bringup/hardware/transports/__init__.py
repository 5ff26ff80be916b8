"""Links to the actuator boards: one ``Transport`` interface, backends chosen by name and imported lazily.

``open_transport("udp", local=..., remote=...)`` or ``open_transport("can", interface="socketcan", channel="can0")``.
Backends live in ``TRANSPORTS`` (name -> (module, class)); other packages can add one through the entry-point
group ``rh5_bringup.transport``. Importing this package does not import python-can.
"""

from __future__ import annotations

import importlib
from importlib.metadata import entry_points
from typing import Any, Final

from rh5_bringup.hardware.transports.base import (
    Transport,
    TransportError,
    TransportInitError,
    TransportOperationError,
    TransportStats,
    TransportTimeoutError,
)

__all__ = [
    "ENTRY_POINT_GROUP",
    "TRANSPORTS",
    "Transport",
    "TransportError",
    "TransportInitError",
    "TransportOperationError",
    "TransportStats",
    "TransportTimeoutError",
    "open_transport",
    "transport_class",
]

TRANSPORTS: Final[dict[str, tuple[str, str]]] = {
    "udp": ("rh5_bringup.hardware.transports.udp", "UdpTransport"),
    "can": ("rh5_bringup.hardware.transports.can", "CanTransport"),
}
ENTRY_POINT_GROUP: Final = "rh5_bringup.transport"


def transport_class(kind: str) -> type[Transport]:
    """The backend class registered as ``kind``, importing its module now.

    :raises ValueError: no backend of that name.
    :raises TransportInitError: the backend's module (or a package it needs) cannot be imported.
    """
    if kind in TRANSPORTS:
        module_name, class_name = TRANSPORTS[kind]
        try:
            cls = getattr(importlib.import_module(module_name), class_name)
        except ImportError as error:
            raise TransportInitError(f"transport {kind!r} is unavailable: {error}") from error
    else:
        plugins = {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}
        if kind not in plugins:
            known = sorted({*TRANSPORTS, *plugins})
            raise ValueError(f"unknown transport {kind!r} (known: {', '.join(known)})")
        try:
            cls = plugins[kind].load()
        except ImportError as error:
            raise TransportInitError(f"transport {kind!r} is unavailable: {error}") from error
    if not (isinstance(cls, type) and issubclass(cls, Transport)):
        raise TransportInitError(f"transport {kind!r} resolves to {cls!r}, not a Transport subclass")
    return cls


def open_transport(kind: str, **kwargs: Any) -> Transport:
    """Open the backend ``kind`` ('udp', 'can' or a plugin) with its keyword arguments."""
    return transport_class(kind)(**kwargs)
