"""ROS 2 names on Zenoh: data key expressions and ROS-graph liveliness tokens (pure).

Two mappings (``Ros2Settings.key_mapping``):

``rmw_zenoh`` -- the ROS 2 middleware over Zenoh (rmw_zenoh ``docs/design.md``, sections
"Topic and Service name mapping to Zenoh key expressions" and "Graph Cache";
``rmw_zenoh_cpp/src/detail/liveliness_utils.cpp``: ``TopicInfo``, ``Entity``,
``mangle_name``, ``qos_to_keyexpr``)::

    <domain_id>/<fully qualified topic, no leading />/<DDS type name>/<type hash>
    0/tb4_1/cmd_vel/geometry_msgs::msg::dds_::Twist_/RIHS01_9c45bf16fe09…

    @ros2_lv/<domain_id>/<zenoh id>/<node id>/<node id>/NN/<enclave>/<namespace>/<node>
    @ros2_lv/<domain_id>/<zenoh id>/<node id>/<entity id>/MP|MS/<enclave>/<namespace>/<node>/
        <topic>/<DDS type name>/<type hash>/<QoS>

  In tokens every ``/`` of a name is written ``%`` (the root namespace and the default
  enclave are just ``%``). Humble's rmw_zenoh has no type hashes: it writes
  ``TypeHashNotSupported`` in their place.

``bridge`` -- zenoh-bridge-ros2dds (the bridge free_fleet uses): ``<namespace>/<topic>``,
  e.g. ``tb4_1/cmd_vel``; the bridge prefixes its namespace to every topic, absolute
  ones included, and carries no type in the key. No liveliness tokens: the bridge makes
  the DDS side's graph.

Names are assumed valid (``fleet.io.settings.Ros2Settings`` checks their syntax).
"""

from __future__ import annotations

from typing import Literal

KeyMapping = Literal["rmw_zenoh", "bridge"]
EntityKind = Literal["NN", "MP", "MS"]  # node, message publisher, message subscription

GRAPH_PREFIX = "@ros2_lv"
HUMBLE_TYPE_HASH = "TypeHashNotSupported"
#: rmw_zenoh's QoS defaults (``qos.cpp``): reliable, volatile, keep last 42; tokens elide them.
DEFAULT_QOS_DEPTH = 42


def fully_qualified(topic: str, namespace: str) -> str:
    """ROS name resolution: ``/x`` stays; ``x`` in namespace ``/ns`` becomes ``/ns/x``."""
    if topic.startswith("/"):
        return topic
    return f"{namespace.rstrip('/')}/{topic}"


def dds_type_name(ros_type: str) -> str:
    """``geometry_msgs/msg/Twist`` -> ``geometry_msgs::msg::dds_::Twist_`` (the CDR type name)."""
    package, kind, name = ros_type.split("/")
    return f"{package}::{kind}::dds_::{name}_"


def mangle(name: str) -> str:
    """A name as a single key chunk: every ``/`` becomes ``%`` (``""`` and ``/`` give ``%``)."""
    return (name or "/").replace("/", "%")


def topic_path(mapping: KeyMapping, topic: str, namespace: str) -> str:
    """The topic's key chunks: the fully qualified name (``rmw_zenoh``) or the bridge's
    namespace prefixed to the topic (``bridge``), without leading or trailing ``/``."""
    if mapping == "rmw_zenoh":
        return fully_qualified(topic, namespace).strip("/")
    return "/".join(p for p in (namespace.strip("/"), topic.strip("/")) if p)


def data_key(mapping: KeyMapping, domain_id: int, path: str, ros_type: str, type_hash: str) -> str:
    """The key a message of ``ros_type`` on the topic at ``path`` is put on."""
    if mapping == "rmw_zenoh":
        return f"{domain_id}/{path}/{dds_type_name(ros_type)}/{type_hash}"
    return path


def any_type_key(mapping: KeyMapping, domain_id: int, path: str) -> str:
    """A subscription to the topic at ``path`` whatever the publisher's type, so a message
    of another type (or another distro's hash) is seen, counted and dropped."""
    if mapping == "rmw_zenoh":
        return f"{domain_id}/{path}/*/*"
    return path


def key_type(mapping: KeyMapping, key: str, domain_id: int, path: str) -> tuple[str, str] | None:
    """(DDS type name, type hash) a received ``rmw_zenoh`` key announces; None for the bridge
    (its keys carry no type) or a key of another topic."""
    prefix = f"{domain_id}/{path}/"
    if mapping != "rmw_zenoh" or not key.startswith(prefix):
        return None
    chunks = key[len(prefix) :].split("/")
    return (chunks[0], chunks[1]) if len(chunks) == 2 else None


def qos_token(*, reliable: bool, depth: int, transient_local: bool = False) -> str:
    """rmw_zenoh's compact QoS (``qos_to_keyexpr``) of a keep-last endpoint:
    ``<reliability>:<durability>:<history>,<depth>:<deadline>:<lifespan>:<liveliness>``,
    each field left empty where it equals the default (reliable = 1, best effort = 2;
    durability volatile = 2, the default, transient-local = 1: rmw's enum values)."""
    reliability = "" if reliable else "2"
    durability = "1" if transient_local else ""
    shown_depth = "" if depth == DEFAULT_QOS_DEPTH else str(depth)
    return f"{reliability}:{durability}:,{shown_depth}:,:,:,,"


def node_token(domain_id: int, zid: str, node_id: int, namespace: str, node_name: str) -> str:
    """Liveliness token announcing a node (``ros2 node list``)."""
    return (
        f"{GRAPH_PREFIX}/{domain_id}/{zid}/{node_id}/{node_id}/NN/%/{mangle(namespace)}/{node_name}"
    )


def endpoint_token(
    kind: EntityKind,
    *,
    domain_id: int,
    zid: str,
    node_id: int,
    entity_id: int,
    namespace: str,
    node_name: str,
    topic: str,
    ros_type: str,
    type_hash: str,
    qos: str,
) -> str:
    """Liveliness token announcing a publisher (``MP``) or subscription (``MS``) of the fully
    qualified ``topic`` (``ros2 topic list``, ``ros2 topic info -v``)."""
    return (
        f"{GRAPH_PREFIX}/{domain_id}/{zid}/{node_id}/{entity_id}/{kind}/%/{mangle(namespace)}/"
        f"{node_name}/{mangle(topic)}/{dds_type_name(ros_type)}/{type_hash}/{qos}"
    )
