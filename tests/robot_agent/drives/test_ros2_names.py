"""ROS names on Zenoh: exact rmw_zenoh / bridge keys and graph tokens.

Oracles: the worked examples of rmw_zenoh's ``docs/design.md`` (copied as literals), and
zenoh-ros2-sdk's key and token builders (an independent implementation).
"""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st
from zenoh_ros2_sdk.entity import EndpointEntity, EntityKind, NodeEntity
from zenoh_ros2_sdk.keyexpr import (
    endpoint_liveliness_keyexpr,
    node_liveliness_keyexpr,
    topic_keyexpr,
)
from zenoh_ros2_sdk.qos import QosProfile, QosReliability

from robot_agent.drives.ros2_messages import TWIST, Ros2Messages
from robot_agent.drives.ros2_names import (
    any_type_key,
    data_key,
    dds_type_name,
    endpoint_token,
    fully_qualified,
    key_type,
    mangle,
    node_token,
    qos_token,
    topic_path,
)

STRING_HASH = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
TWIST_HASH = "RIHS01_9c45bf16fe0983d80e3cfe750d6835843d265a9a6c46bd2e609fcddde6fb8d2a"
ZID = "aac3178e146ba6f1fc6e6a4085e77f21"

token = st.from_regex(r"[A-Za-z_][A-Za-z0-9_]{0,8}", fullmatch=True)
namespaces = st.one_of(st.just(""), st.just("/"), st.lists(token, min_size=1, max_size=3).map(
    lambda parts: "/" + "/".join(parts)
))  # fmt: skip
topics = st.tuples(st.booleans(), st.lists(token, min_size=1, max_size=3)).map(
    lambda t: ("/" if t[0] else "") + "/".join(t[1])
)


def test_design_md_examples() -> None:
    """rmw_zenoh docs/design.md: the chatter keys and the listener's graph tokens."""
    assert Ros2Messages().type_hash("std_msgs/msg/String") == STRING_HASH
    chatter = "std_msgs/msg/String"
    root = topic_path("rmw_zenoh", "chatter", "")
    assert data_key("rmw_zenoh", 0, root, chatter, STRING_HASH) == (
        f"0/chatter/std_msgs::msg::dds_::String_/{STRING_HASH}"
    )
    robot1 = topic_path("rmw_zenoh", "chatter", "/robot1")
    assert data_key("rmw_zenoh", 0, robot1, chatter, STRING_HASH) == (
        f"0/robot1/chatter/std_msgs::msg::dds_::String_/{STRING_HASH}"
    )
    assert node_token(2, ZID, 0, "", "listener") == f"@ros2_lv/2/{ZID}/0/0/NN/%/%/listener"
    common = {"domain_id": 2, "zid": ZID, "node_id": 0, "entity_id": 10, "namespace": ""}
    subscription = endpoint_token(
        "MS", **common, node_name="listener", topic="/chatter", ros_type=chatter,
        type_hash=STRING_HASH, qos=qos_token(reliable=True, depth=10),
    )  # fmt: skip
    assert subscription == (
        f"@ros2_lv/2/{ZID}/0/10/MS/%/%/listener/%chatter/std_msgs::msg::dds_::String_/"
        f"{STRING_HASH}/::,10:,:,:,,"
    )
    assert qos_token(reliable=True, depth=7) == "::,7:,:,:,,"  # the talker's publisher


def test_cmd_vel_keys_in_a_namespace_and_through_the_bridge() -> None:
    twist = dds_type_name(TWIST)
    assert twist == "geometry_msgs::msg::dds_::Twist_"
    rel = topic_path("rmw_zenoh", "cmd_vel", "/tb4_1")
    assert (
        data_key("rmw_zenoh", 3, rel, TWIST, TWIST_HASH) == f"3/tb4_1/cmd_vel/{twist}/{TWIST_HASH}"
    )
    assert any_type_key("rmw_zenoh", 3, rel) == "3/tb4_1/cmd_vel/*/*"
    # an absolute name ignores the namespace in ROS; the bridge prefixes its namespace anyway
    assert topic_path("rmw_zenoh", "/cmd_vel", "/tb4_1") == "cmd_vel"
    assert topic_path("bridge", "/cmd_vel", "/tb4_1") == "tb4_1/cmd_vel"
    assert topic_path("bridge", "cmd_vel", "") == "cmd_vel"
    assert data_key("bridge", 3, "tb4_1/cmd_vel", TWIST, TWIST_HASH) == "tb4_1/cmd_vel"
    assert any_type_key("bridge", 3, "tb4_1/cmd_vel") == "tb4_1/cmd_vel"
    assert qos_token(reliable=False, depth=5) == "2::,5:,:,:,,"
    assert qos_token(reliable=True, depth=42) == "::,:,:,:,,"  # rmw_zenoh's default depth


@given(topics, namespaces, st.integers(0, 232), st.sampled_from(["std_msgs/msg/String", TWIST]))
def test_keys_and_tokens_agree_with_zenoh_ros2_sdk(
    topic: str, namespace: str, domain: int, ros_type: str
) -> None:
    name = fully_qualified(topic, namespace)
    path = topic_path("rmw_zenoh", topic, namespace)
    ours = data_key("rmw_zenoh", domain, path, ros_type, TWIST_HASH)
    assert ours == topic_keyexpr(domain, name, dds_type_name(ros_type), TWIST_HASH)
    node = NodeEntity(domain, ZID, 4, "parkfleet_r1", namespace or "/")
    assert node_token(domain, ZID, 4, namespace, "parkfleet_r1") == node_liveliness_keyexpr(node)
    qos = qos_token(reliable=False, depth=5)
    sdk = EndpointEntity(node, 7, EntityKind.PUBLISHER, name, dds_type_name(ros_type), "h", qos)
    assert endpoint_token(
        "MP", domain_id=domain, zid=ZID, node_id=4, entity_id=7, namespace=namespace,
        node_name="parkfleet_r1", topic=name, ros_type=ros_type, type_hash="h", qos=qos,
    ) == endpoint_liveliness_keyexpr(sdk)  # fmt: skip
    decoded = QosProfile.decode(qos)
    assert decoded.reliability is QosReliability.BEST_EFFORT and decoded.history_depth == 5


@given(topics, namespaces, st.integers(0, 232))
def test_a_received_key_names_its_type_only_on_its_own_topic(
    topic: str, namespace: str, domain: int
) -> None:
    path = topic_path("rmw_zenoh", topic, namespace)
    key = data_key("rmw_zenoh", domain, path, TWIST, TWIST_HASH)
    assert key_type("rmw_zenoh", key, domain, path) == (dds_type_name(TWIST), TWIST_HASH)
    assert key_type("rmw_zenoh", key, domain + 1, path) is None
    assert (
        key_type("rmw_zenoh", f"{domain}/{path}/x/{dds_type_name(TWIST)}/h", domain, path) is None
    )
    assert key_type("bridge", key, domain, path) is None  # bridge keys carry no type
    assert "/" not in mangle(fully_qualified(topic, namespace))
    assert mangle(fully_qualified(topic, namespace)).replace("%", "/") == fully_qualified(
        topic, namespace
    )
