"""Detect whether this process runs in the loopback-only network namespace (no rclpy here).

Every process that starts rclpy in tests and in the demo must run inside a private network
namespace that holds only ``lo`` (``scripts/netns.sh``), so that DDS discovery can neither leave
the machine nor meet another run. ``GEODESIC_PLANNER_NETNS=off`` opts out (real deployments).
"""
from __future__ import annotations

import os
from pathlib import Path

__all__ = [
    'ENV_OPT_OUT',
    'is_loopback_only',
    'isolation_disabled',
    'isolation_problem',
    'network_interfaces',
    'parse_proc_net_dev',
    'worker_domain',
]

#: Environment variable that disables the namespace requirement when set to ``off``.
ENV_OPT_OUT = 'GEODESIC_PLANNER_NETNS'

_PROC_NET_DEV = Path('/proc/self/net/dev')


def parse_proc_net_dev(text: str) -> list[str]:
    """Interface names listed in the text of ``/proc/net/dev``.

    Args:
        text: contents of ``/proc/self/net/dev`` (two header lines, then ``name: counters``).

    Returns:
        Interface names in file order, e.g. ``['lo', 'eth0']``.
    """
    names = []
    for line in text.splitlines()[2:]:
        name, sep, _ = line.partition(':')
        if sep and name.strip():
            names.append(name.strip())
    return names


def network_interfaces(proc_net_dev: Path = _PROC_NET_DEV) -> list[str]:
    """Network interfaces of this process's network namespace.

    ``/proc/self/net/dev`` always describes the caller's namespace, whereas ``/sys/class/net``
    describes the namespace that mounted sysfs (``scripts/netns.sh`` remounts it so both agree).

    Args:
        proc_net_dev: file to read (for tests).

    Returns:
        Interface names, e.g. ``['lo']`` inside ``scripts/netns.sh``.
    """
    return parse_proc_net_dev(proc_net_dev.read_text())


def is_loopback_only(interfaces: list[str] | None = None) -> bool:
    """True when the namespace holds exactly one interface, ``lo``.

    Args:
        interfaces: interface names; default: :func:`network_interfaces`.
    """
    if interfaces is None:
        interfaces = network_interfaces()
    return list(interfaces) == ['lo']


def isolation_disabled(environ: dict[str, str] | None = None) -> bool:
    """True when ``GEODESIC_PLANNER_NETNS`` is ``off`` (also ``0``, ``false``, ``no``)."""
    env = os.environ if environ is None else environ
    return env.get(ENV_OPT_OUT, '').strip().lower() in ('off', '0', 'false', 'no')


def isolation_problem(interfaces: list[str] | None = None,
                      environ: dict[str, str] | None = None) -> str | None:
    """Why starting rclpy here would be unsafe, or None when it is fine.

    Fine means: inside a loopback-only namespace, or the opt-out is set.

    Args:
        interfaces: interface names; default: :func:`network_interfaces`.
        environ: environment; default: ``os.environ``.

    Returns:
        A one-line explanation naming the interfaces seen and how to fix it, or None.
    """
    if isolation_disabled(environ):
        return None
    if interfaces is None:
        interfaces = network_interfaces()
    if is_loopback_only(interfaces):
        return None
    return (f'not inside a loopback-only network namespace (interfaces: {", ".join(interfaces)}): '
            'run through scripts/netns.sh (bash scripts/test.sh and bash scripts/demo.sh do), '
            f'or set {ENV_OPT_OUT}=off to run without isolation')


#: ROS domain of xdist worker ``gwN``: WORKER_DOMAIN_BASE + N (a plain run keeps the caller's).
WORKER_DOMAIN_BASE = 11


def worker_domain(worker: str | None) -> int | None:
    """The ROS domain id of xdist worker ``worker`` ('gw0', 'gw1', ...); None outside xdist."""
    if not worker or not worker.startswith('gw') or not worker[2:].isdigit():
        return None
    return WORKER_DOMAIN_BASE + int(worker[2:])
