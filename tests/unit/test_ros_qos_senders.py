"""/rosout's QoS as rmw_zenoh writes it in a token, and which publishers' departure ends a
trajectory (busarm.ros.commands.Publishers), without a network."""

from __future__ import annotations

from busarm.protocol.rmw_zenoh import (
    ROSOUT,
    Entity,
    Qos,
    gid_of,
)
from busarm.ros.commands import Publishers
from busarm.ros.messages import JOINT_TRAJECTORY, STRING, ros_type

ZID = "1863437b7dc1c46969bfaff068f33402"


def token(entity_id: int, topic: str = "/joint_trajectory", kind: str = "MP",
          type_name: str = JOINT_TRAJECTORY) -> str:
    return Entity(0, ZID, 0, entity_id, kind, "n", topic=topic, ros_type=type_name,
                  type_hash=ros_type(type_name).type_hash, qos=Qos()).token()


def test_rosout_is_rcls_logging_qos_in_rmw_zenohs_words() -> None:
    # rcl_qos_profile_rosout_default: keep last 1000, reliable, transient local, lifespan
    # {10, 0}; each field only where it differs from rmw_zenoh's default, s and ns apart.
    assert ROSOUT.key() == ":1:,1000:,:10,:,,"
    assert Qos(lifespan_ns=1_500_000_000).key() == "::,:,:1,500000000:,,"
    assert Qos.parse(":1:,1000:,:10,:,,") == ROSOUT


def test_a_hash_gid_names_its_own_publisher_any_other_names_every_one_there() -> None:
    senders = Publishers("/joint_trajectory")
    a, b = token(1), token(2)
    for key in (a, b, token(3, kind="MS"), token(4, "/other", type_name=STRING), "x/y"):
        senders.update(key, alive=True)
    assert senders.of(gid_of(a)) == {a}  # rmw_zenoh's rule: exactly the sender
    assert senders.of(b"\x5a" * 16) == {a, b}  # not a token's hash: any may have sent it
    assert senders.present(frozenset({a, b}))
    senders.update(a, alive=False)
    assert not senders.present(frozenset({a, b}))
    assert senders.of(gid_of(a)) == {b}  # gone: only those still there
    senders.update(b, alive=False)
    assert senders.of(b"\x5a" * 16) == frozenset()  # none: no departure can be seen
