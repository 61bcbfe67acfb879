"""The robot's dynamic limits: the arm's velocities read from its URDF (what PyBullet reports for
the arm the scene loads), Franka's accelerations, and refusals that name the file and joint."""

from __future__ import annotations

from pathlib import Path

import pybullet as p
import pytest

from stalm.errors import StalmError
from stalm.world.robot_limits import (
    ARM_JOINT_NAMES,
    FRANKA_ACCELERATION,
    LIFT_JOINT_NAME,
    JointLimits,
    panda_limits,
    urdf_velocity_limits,
)


def test_the_arms_velocity_limits_are_pybullets_for_the_loaded_urdf(domain_factory) -> None:
    sim = domain_factory("P2").sim
    arm, client = sim.bodies.arm, sim.client
    info = [p.getJointInfo(arm, joint, physicsClientId=client) for joint in range(7)]
    assert tuple(row[1].decode() for row in info) == ARM_JOINT_NAMES
    limits = panda_limits()
    assert limits.arm.names == (LIFT_JOINT_NAME, *ARM_JOINT_NAMES)
    assert limits.arm.velocity[1:] == tuple(row[11] for row in info)  # maxVelocity
    assert limits.arm.velocity[1:] == (2.175,) * 4 + (2.61,) * 3
    assert limits.arm.acceleration[1:] == FRANKA_ACCELERATION
    assert len(limits.urdf_sha256) == 64 and limits.urdf == "franka_panda/panda.urdf"


def _urdf(tmp_path: Path, limit: str) -> Path:
    path = tmp_path / "arm.urdf"
    path.write_text(
        f'<robot name="r"><link name="a"/><link name="b"/><joint name="j1" type="revolute">'
        f'<parent link="a"/><child link="b"/>{limit}</joint></robot>',
        encoding="utf-8",
    )
    return path


def test_a_urdf_gives_its_own_velocity_limits(tmp_path) -> None:
    path = _urdf(tmp_path, '<limit lower="-1" upper="1" effort="5" velocity="0.7"/>')
    assert urdf_velocity_limits(path, ["j1"]) == (0.7,)


@pytest.mark.parametrize(
    ("limit", "joint", "message"),
    [
        ("", "j1", "joint 'j1' has no positive <limit velocity=...> (got None)"),
        ('<limit velocity="fast"/>', "j1", "(got 'fast')"),
        ('<limit velocity="0"/>', "j1", "(got '0')"),
        ('<limit velocity="1"/>', "j2", "no joint 'j2'"),
    ],
)
def test_a_urdf_without_a_usable_velocity_limit_is_refused(tmp_path, limit, joint, message):
    path = _urdf(tmp_path, limit)
    with pytest.raises(StalmError, match=r"arm\.urdf") as error:
        urdf_velocity_limits(path, [joint])
    assert message in str(error.value)


def test_an_unreadable_urdf_is_refused(tmp_path) -> None:
    with pytest.raises(StalmError, match="cannot read the URDF"):
        urdf_velocity_limits(tmp_path / "missing.urdf", ["j1"])


@pytest.mark.parametrize("velocity", [0.0, -1.0, float("nan"), float("inf")])
def test_joint_limits_must_be_positive_and_finite(velocity) -> None:
    with pytest.raises(ValueError, match="joint a"):
        JointLimits(("a",), (velocity,), (1.0,))
    with pytest.raises(ValueError, match="a limit for every joint"):
        JointLimits(("a", "b"), (1.0,), (1.0,))
