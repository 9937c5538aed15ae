"""The ROS 2 Jazzy typestore with hil's own message types registered.

hil's types live as ``.msg`` files in ``hil/replay/msg/`` (ROS package
``hil_msgs``), so any ROS 2 tool can decode them from the schema stored in the
bag: the MCAP schema of each channel carries the full definition text, its
dependencies appended as ``rosbag2`` and ``ros2 bag`` write them.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore
from rosbags.typesys.base import TypesysError
from rosbags.typesys.store import Typestore

from hil.bag.errors import SchemaError

MSG_DIR = Path(__file__).parent / "msg"
"""Directory of hil's ``.msg`` files."""

PACKAGE = "hil_msgs"
"""ROS package name of hil's message types."""

DECISION = f"{PACKAGE}/msg/Decision"
POLYGON_2D = f"{PACKAGE}/msg/Polygon2D"
OBSTACLE_LAYOUT = f"{PACKAGE}/msg/ObstacleLayout"
THRUSTER_COMMANDS = f"{PACKAGE}/msg/ThrusterCommands"
EVENT = f"{PACKAGE}/msg/Event"
CONTROLLER_READY = f"{PACKAGE}/msg/ControllerReady"
QTM_6D = f"{PACKAGE}/msg/Qtm6D"


def hil_type_names() -> tuple[str, ...]:
    """Return the full names (``hil_msgs/msg/X``) of every shipped ``.msg`` file, sorted."""
    return tuple(f"{PACKAGE}/msg/{path.stem}" for path in sorted(MSG_DIR.glob("*.msg")))


def register_hil_types(store: Typestore) -> None:
    """Register every ``hil_msgs`` type from its ``.msg`` file in ``store``.

    Args:
        store: Typestore to extend (a fresh Jazzy store, typically).

    Raises:
        SchemaError: A ``.msg`` file cannot be parsed, or conflicts with a type in ``store``.
    """
    types = {}
    for path in sorted(MSG_DIR.glob("*.msg")):
        name = f"{PACKAGE}/msg/{path.stem}"
        try:
            types.update(get_types_from_msg(path.read_text(encoding="utf-8"), name))
        except TypesysError as err:
            raise SchemaError(f"cannot parse message definition {str(path)!r}: {err}") from err
    try:
        store.register(types)
    except TypesysError as err:
        raise SchemaError(f"cannot register hil's message types: {err}") from err


@functools.cache
def _jazzy() -> Typestore:
    return get_typestore(Stores.ROS2_JAZZY)


def copy_typestore(store: Typestore, warm: Iterable[str] = ()) -> Typestore:
    """Return an independent copy of `store` that shares its classes and compiled codecs.

    rosbags generates (de)serializers per type on first use (milliseconds each);
    the codecs of the types in `warm` that `store` knows are generated in `store`
    first, so every copy reuses them. Registering into the copy leaves `store`
    alone.
    """
    for typename in warm:
        if typename in store.fielddefs:
            store.get_msgdef(typename)
    copy = Typestore(max_sequence_length=store.max_sequence_length)
    copy.fielddefs = dict(store.fielddefs)
    copy.types = dict(store.types)
    copy.cache = dict(store.cache)
    return copy


def jazzy_typestore(warm: Iterable[str] = ()) -> Typestore:
    """Return a new ROS 2 Jazzy typestore without hil's types (for a bag's own schemas).

    Args:
        warm: Type names whose codecs to generate once per process and share.
    """
    return copy_typestore(_jazzy(), warm)


@functools.lru_cache(maxsize=256)
def parse_schema(encoding: str, text: str, typename: str) -> dict[str, Any]:
    """Parse a ``ros2msg`` or ``ros2idl`` schema into rosbags' type dictionary (cached).

    Raises:
        SchemaError: The schema cannot be parsed.
    """
    try:
        if encoding == "ros2msg":
            return dict(get_types_from_msg(text, typename))
        if encoding == "ros2idl":
            return dict(get_types_from_idl(text))
    except Exception as err:
        first_line = (str(err).strip().splitlines() or [type(err).__name__])[0]
        raise SchemaError(first_line) from err
    raise SchemaError(f"schema encoding {encoding!r} is not ros2msg or ros2idl")


def _fields(definition: Any) -> list[tuple[str, Any]]:
    return [(str(name).lower(), kind) for name, kind in definition[1]]


def register_new(store: Typestore, types: dict[str, Any]) -> None:
    """Register the types `store` lacks; check the others are the same definition.

    Raises:
        SchemaError: A type is present with a different definition.
    """
    new = {}
    for name, definition in types.items():
        have = store.fielddefs.get(name)
        if have is None:
            new[name] = definition
        elif _fields(have) != _fields(definition):
            raise SchemaError(f"type {name!r} differs from the ROS 2 Jazzy definition")
    if new:
        try:
            store.register(new)
        except TypesysError as err:
            raise SchemaError(str(err)) from err


def new_typestore() -> Typestore:
    """Return a new ROS 2 Jazzy typestore with hil's types registered."""
    store = jazzy_typestore()
    register_hil_types(store)
    return store


@functools.cache
def typestore() -> Typestore:
    """Return the shared Jazzy + ``hil_msgs`` typestore used for writing (do not extend it)."""
    return new_typestore()


@functools.cache
def schema_text(typename: str) -> str:
    """Return the ``ros2msg`` schema of ``typename`` with its dependencies appended.

    Args:
        typename: Full type name, e.g. ``"sensor_msgs/msg/Imu"``.

    Returns:
        The definition text as stored in an MCAP ``Schema`` record.

    Raises:
        SchemaError: The type is unknown.
    """
    try:
        text, _digest = typestore().generate_msgdef(typename, ros_version=2)
    except (KeyError, TypesysError) as err:
        raise SchemaError(f"unknown message type {typename!r}") from err
    return text
