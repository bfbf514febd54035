"""push_ros.message_info: goal_pose samples de-duplicated, other publishers detected (no DDS)."""

from __future__ import annotations

from push_ros.message_info import GoalSources, publisher_of, sample_key


def info(sequence: object, stamp: object = 5, gid: object = None) -> dict[str, object]:
    d: dict[str, object] = {"publication_sequence_number": sequence, "source_timestamp": stamp}
    if gid is not None:
        d["publisher_gid"] = gid
    return d


def test_sample_key_and_publisher_of_read_only_well_typed_entries() -> None:
    assert sample_key(info(3, 7)) == (3, 7)
    assert sample_key(None) is None and sample_key({}) is None
    assert sample_key(info(True, 7)) is None and sample_key(info(3, "7")) is None
    assert publisher_of(info(3, gid={"data": [1, 2, 255]})) == ("gid 01.02.ff", 3)
    assert publisher_of(info(3, gid=b"\x0a\x0b")) == ("gid 0a.0b", 3)
    assert publisher_of(info(3, gid="bad")) == ("", 3)
    assert publisher_of(info(False)) == ("", None)
    assert publisher_of("not a dict") == ("", None)


def test_a_sample_on_both_readers_is_taken_once() -> None:
    g = GoalSources(kept=2)
    assert not g.duplicate(info(1, 10)) and g.duplicate(info(1, 10))
    assert not g.duplicate(info(2, 10)) and not g.duplicate(info(3, 10))
    assert not g.duplicate(info(1, 10))  # forgotten beyond ``kept``
    assert not g.duplicate(None) and not g.duplicate(None)  # unknown: never a duplicate


def test_a_goal_whose_sequence_does_not_follow_is_from_another_publisher() -> None:
    g = GoalSources()
    g.arrived(info(1))
    assert not g.take(have_goal=False)  # an episode's first goal never counts
    g.arrived(info(2))
    assert not g.take(have_goal=True)  # 2 follows 1
    g.arrived(info(1))  # another writer's first sample
    assert g.take(have_goal=True)
    g.arrived(info(7))  # refused by the node (not taken), still counted by the rule
    g.arrived(info(8))
    assert not g.take(have_goal=True)
    g.forget()  # a new episode: no previous number
    g.arrived(info(42))
    assert not g.take(have_goal=True)


def test_a_gid_decides_when_the_info_has_one() -> None:
    g = GoalSources()
    assert g.arrived(info(1, gid=[1])) == "gid 01"
    assert not g.take(have_goal=False) and g.source == "gid 01"
    g.arrived(info(9, gid=[1]))  # sequence jumps, same GID: the same publisher
    assert not g.take(have_goal=True)
    g.arrived(info(10, gid=[2]))
    assert g.take(have_goal=True) and g.source == "gid 02"
