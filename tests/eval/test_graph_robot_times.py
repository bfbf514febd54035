"""Robot time of a graph episode from the stamps its client saw
(pushbot.runner.graph_record.graph_robot_times), against hand-computed values."""

from __future__ import annotations

import math

import pytest

from pushbot.runner.graph_record import graph_robot_times


def test_goal_to_the_frame_after_the_last_executed_push() -> None:
    times = graph_robot_times(100.0, 99.0, [100.5, 103.0, 107.5], 110.0)
    assert times["robot_time_s"] == pytest.approx(10.0)
    assert times["cycle_s"] == pytest.approx([2.5, 4.5])


def test_commands_before_the_goal_are_another_clients_and_the_goal_is_at_most_the_first() -> None:
    # a push stamped 0 (another client) is not this episode's; a first push stamped a little
    # before the client's clock (the nodes' /clock deliveries differ) moves the goal to it
    times = graph_robot_times(50.0, 49.0, [0.0, 49.8, 52.0], 55.0)
    assert times["robot_time_s"] == pytest.approx(55.0 - 49.8)
    assert times["cycle_s"] == pytest.approx([2.2])


def test_nothing_executed_ends_at_the_last_command() -> None:
    # every push refused (e.g. the arm's executor): the commands still took robot time
    times = graph_robot_times(1159.634, 1159.0, [1159.654, 1161.468, 1163.554], None)
    assert times["robot_time_s"] == pytest.approx(1163.554 - 1159.634)
    assert times["cycle_s"] == pytest.approx([1161.468 - 1159.654, 1163.554 - 1161.468])


def test_no_clock_at_the_goal_starts_at_the_first_frame_and_no_push_is_zero() -> None:
    assert graph_robot_times(-math.inf, 20.0, [], None) == {"robot_time_s": 0.0, "cycle_s": []}
    times = graph_robot_times(math.nan, 20.0, [21.0], 24.0)
    assert times["robot_time_s"] == pytest.approx(4.0) and times["cycle_s"] == []
