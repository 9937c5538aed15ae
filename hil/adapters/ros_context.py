"""Starting and stopping rclpy: a context on a domain, a node spun in a thread.

Every ROS 2 node of hil (the stack's world, the preflight's listener, the simulated
vessel) starts through :func:`init_context` and :func:`spin_in_thread` and stops
through :func:`stop_spinning`; rclpy is imported only inside them.
"""

from __future__ import annotations

import contextlib
import os
import threading
from typing import Any

__all__ = [
    "MAX_DOMAIN_ID",
    "RosBackendError",
    "check_domain_id",
    "init_context",
    "spin_in_thread",
    "stop_spinning",
]


class RosBackendError(RuntimeError):
    """The ROS 2 backend cannot start or lost its link."""


# DDS maps a domain to UDP ports; above 232 they leave the valid range (ROS 2 docs,
# "The ROS_DOMAIN_ID").
MAX_DOMAIN_ID = 232


def check_domain_id(value: object, what: str) -> int:
    """Return `value` as a ROS domain id, or raise ValueError naming `what` and the value."""
    if isinstance(value, bool) or not isinstance(value, int | str):
        raise ValueError(f"{what} must be an integer 0..{MAX_DOMAIN_ID}, got {value!r}")
    try:
        domain = int(value)
    except ValueError:
        domain = -1
    if not 0 <= domain <= MAX_DOMAIN_ID:
        raise ValueError(f"{what} must be an integer 0..{MAX_DOMAIN_ID}, got {value!r}")
    return domain


def spin_in_thread(context: Any, node: Any, name: str) -> tuple[Any, threading.Thread]:
    """Spin `node` on an executor of `context` in a daemon thread; return both.

    The thread ends when the context shuts down (rclpy's ExternalShutdownException).
    """
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)

    def spin() -> None:
        with contextlib.suppress(ExternalShutdownException):
            executor.spin()

    thread = threading.Thread(target=spin, name=name, daemon=True)
    thread.start()
    return executor, thread


def stop_spinning(context: Any, node: Any, executor: Any, thread: threading.Thread | None) -> None:
    """Undo :func:`spin_in_thread`: stop the executor, destroy the node, shut the context."""
    executor.shutdown()
    node.destroy_node()
    if context.ok():
        context.try_shutdown()
    if thread is not None:
        thread.join(timeout=2.0)


def init_context(
    rclpy: Any, context: Any, domain_id: int | None, ros_args: tuple[str, ...] = ()
) -> int:
    """Initialize an rclpy context on `domain_id`, else on ROS_DOMAIN_ID (default 0).

    `ros_args` (remapping rules and parameters, as after ``--ros-args``) apply to every
    node of the context.

    Returns:
        The domain joined.

    Raises:
        RosBackendError: ROS_DOMAIN_ID is not a valid domain, or rclpy refused.
    """
    if domain_id is None:
        try:
            domain = check_domain_id(os.environ.get("ROS_DOMAIN_ID", "0") or "0",
                                     "ROS_DOMAIN_ID")
        except ValueError as err:
            raise RosBackendError(str(err)) from err
    else:
        domain = domain_id
    try:
        args = ["hil", "--ros-args", *ros_args] if ros_args else None
        rclpy.init(args=args, context=context, domain_id=domain)
    except Exception as err:  # rclpy raises its own RCLError types
        given = f" with --ros-args {' '.join(ros_args)}" if ros_args else ""
        raise RosBackendError(f"cannot start ROS 2 on domain {domain!r}{given}: {err}") from err
    return domain
