"""New layouts that load the first time: the base roadmap through a doorway moved anywhere.

P2's 1.6 m doorway is moved along the kitchen-hall divider (with its door and the door's
standing poses). Every layout must load (every standing pose reachable with the doors open).
Without the doorway's passage nodes the doorway at y 2.0-3.6 read as a wall; with them it does
not. When a pose really is unreachable, the fault names why.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from stalm.motion.problem_check import problem_geometry_faults
from stalm.motion.roadmap import RoadmapSettings, passage_points
from stalm.world.problem import Problem, load_problem, shipped_problems_dir

DOORWAY = 1.6
P2_FILE = shipped_problems_dir() / "p2.yaml"


def doorway_at(low: float, folder: Path, width: float = DOORWAY) -> Problem:
    """P2 with its doorway spanning y in [low, low + width] of the divider at x = -1.5."""
    data = yaml.safe_load(P2_FILE.read_text())
    walls = {wall["name"]: wall for wall in data["walls"]}
    walls["wall_divider_south"].update(
        center=[-1.5, (low - 5.0) / 2, 1.1], size=[0.1, low + 5.0, 2.2]
    )
    top = low + width
    walls["wall_divider_north"].update(
        center=[-1.5, (top + 5.0) / 2, 1.1], size=[0.1, 5.0 - top, 2.2]
    )
    door = data["doors"][0]
    door.update(hinge=[-1.5, low], width=width, handle_offset=width - 0.15)
    door["base_poses"] = [[-0.85, top - 0.25, 3.141593], [-2.15, top - 0.25, 0.0]]
    path = folder / f"p2-doorway-{low}.yaml"
    path.write_text(yaml.safe_dump(data))
    return load_problem(path)


@pytest.mark.parametrize(
    "low",
    [
        2.0,
        pytest.param(3.3, marks=pytest.mark.slow),
        -1.0,
        pytest.param(-4.0, marks=pytest.mark.slow),
    ],
)
def test_a_doorway_anywhere_along_the_divider_loads(tmp_path: Path, low: float) -> None:
    assert problem_geometry_faults(doorway_at(low, tmp_path)) == []


def test_without_passage_nodes_the_doorway_at_two_metres_reads_as_a_wall(tmp_path: Path) -> None:
    """The failure the passage nodes mend, with the default seed (so the test above is not
    vacuous)."""
    faults = problem_geometry_faults(
        doorway_at(2.0, tmp_path), RoadmapSettings(passage_nodes=False)
    )
    assert faults and all("the base cannot drive there" in fault for fault in faults)
    assert "roadmap found no route" in faults[0]


def test_passage_points_sit_in_and_beside_each_doorway(problems: dict[str, Problem]) -> None:
    door = problems["P2"].spec.doors[0]  # hinge (-1.5, -4.6), closed along +y, 1.6 m wide
    points = passage_points(problems["P2"].spec)
    assert points[0] == pytest.approx((-1.5, -4.6 + door.width / 2))
    assert sorted(round(x, 6) for x, _ in points) == [-2.2, -1.85, -1.5, -1.15, -0.8]
    assert all(y == pytest.approx(-3.8) for _, y in points)


def test_a_doorway_narrower_than_the_robot_is_named(tmp_path: Path) -> None:
    faults = problem_geometry_faults(doorway_at(-1.0, tmp_path, width=0.5))
    assert faults
    assert (
        "the doorway of 'kitchen_door' is 0.50 m wide, narrower than the robot (0.64 m)"
        in (faults[0])
    )
