"""ROS 2 names: node names, namespaces and topic names, resolved as ``rcl`` resolves them, and
the DDS topic of a ROS 2 topic (``/x`` is ``rt/x``).

A topic name is absolute (``/a/b``), relative to the node's namespace (``a/b``) or private to
the node (``~/a``, i.e. ``<namespace>/<node>/a``). Each token is letters, digits and
underscores, not starting with a digit; no ``//``, no trailing ``/``.
"""

from __future__ import annotations

import re

from .errors import RosConfigError

_TOKEN = r"[A-Za-z_][A-Za-z0-9_]*"
NODE_NAME = re.compile(rf"^{_TOKEN}$")
NAMESPACE = re.compile(rf"^/(?:{_TOKEN}(?:/{_TOKEN})*)?$")
TOPIC_NAME = re.compile(rf"^(?:~|~/{_TOKEN}(?:/{_TOKEN})*|/?{_TOKEN}(?:/{_TOKEN})*)$")
#: what ROS 2 prefixes to a topic's name to make the DDS topic name
TOPIC_PREFIX = "rt"


def check_node_name(name: str) -> str:
    """``name`` if it is a valid ROS 2 node name.

    Raises:
        RosConfigError: it is not (it names the rule).
    """
    if not NODE_NAME.match(name):
        raise RosConfigError(f"node name {name!r} is not a ROS 2 node name: letters, digits and underscores, "
                             "not starting with a digit (e.g. \"wbc\")")
    return name


def check_namespace(namespace: str) -> str:
    """``namespace`` in its absolute form (``"robot1"`` -> ``"/robot1"``).

    Raises:
        RosConfigError: it is not a valid ROS 2 namespace.
    """
    absolute = namespace if namespace.startswith("/") else "/" + namespace
    if not NAMESPACE.match(absolute):
        raise RosConfigError(f"namespace {namespace!r} is not a ROS 2 namespace: \"/\" or \"/a/b\", tokens of "
                             "letters, digits and underscores not starting with a digit, no trailing \"/\"")
    return absolute


def resolve_topic(name: str, namespace: str = "/", node: str = "wbc") -> str:
    """The fully qualified name of topic ``name`` of node ``node`` in ``namespace``.

    Raises:
        RosConfigError: ``name`` is not a valid ROS 2 topic name (or the node or namespace is invalid).
    """
    namespace, node = check_namespace(namespace), check_node_name(node)
    if not TOPIC_NAME.match(name):
        raise RosConfigError(f"topic {name!r} is not a ROS 2 topic name: \"/absolute/name\", \"relative/name\" or "
                             "\"~/private_name\", tokens of letters, digits and underscores not starting with a digit, "
                             "no \"//\" or trailing \"/\"")
    base = namespace.rstrip("/")
    if name.startswith("~"):
        return f"{base}/{node}{name[1:]}"
    if name.startswith("/"):
        return name
    return f"{base}/{name}"


def dds_topic(ros_topic: str) -> str:
    """The DDS topic name of a fully qualified ROS 2 topic name (``/joint_states`` -> ``rt/joint_states``)."""
    return TOPIC_PREFIX + ros_topic
