"""One pushbot graph per ROS domain (pushbot.runner.domain): a second ``pushbot up`` / ``demo``
on a domain where a graph runs is refused with one line naming a free domain.

In-process: the lock of this session's domain held by a first claim; a node named like one of
the graph's (``planner_node``) answering on the domain. The end-to-end refusal of a second
``pushbot up`` next to a running one is in tests/cli/test_graph_tools.py.
"""

from __future__ import annotations

import os
import re
from typing import Any

import pytest

from pushbot.runner.domain import claim_domain, free_domain, lock_path

pytestmark = pytest.mark.ros

DOMAIN = int(os.environ.get("ROS_DOMAIN_ID", "0"))


def suggested(refusal: str) -> int:
    match = re.search(r"ROS_DOMAIN_ID=(\d+) pushbot", refusal)
    assert match, refusal
    return int(match.group(1))


def test_a_claimed_domain_is_refused_naming_a_free_one() -> None:
    first, refusal = claim_domain("up", probe_time=0.2)
    assert first is not None and refusal == ""
    try:
        second, refusal = claim_domain("demo", probe_time=0.2)
        assert second is None
        assert refusal.startswith(f"pushbot demo: a pushbot graph already runs on "
                                  f"ROS_DOMAIN_ID={DOMAIN} (held by pushbot up, pid "
                                  f"{os.getpid()})")
        assert "\n" not in refusal and suggested(refusal) != DOMAIN
        assert suggested(refusal) == free_domain(DOMAIN)
    finally:
        first.release()
    again, _ = claim_domain("up", probe_time=0.2)  # released: the domain is free again
    assert again is not None
    again.release()
    assert lock_path(DOMAIN).exists()


def test_a_graph_node_answering_on_the_domain_is_refused(ros_context: Any) -> None:
    from rclpy.node import Node

    node = Node("planner_node", context=ros_context)
    try:
        claim, refusal = claim_domain("up", probe_time=10.0)  # ends at the first node seen
        assert claim is None
        assert "(its nodes planner_node answer)" in refusal and suggested(refusal) != DOMAIN
    finally:
        node.destroy_node()
