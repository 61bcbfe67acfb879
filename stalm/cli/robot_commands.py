"""``stalm robot list`` and ``stalm robot check``: the robots stalm knows, and what a robot file
says and implies, with its sphere model's conservativeness check."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated

import numpy as np
import typer

from stalm.cli.display import printable
from stalm.errors import StalmError

if TYPE_CHECKING:
    from stalm.world.robot_description import Robot

robot_app = typer.Typer(
    name="robot",
    help="Robots described as data: list the built-in ones, check a robot file.",
    no_args_is_help=True,
)


@robot_app.command("list")
def list_command() -> None:
    """The built-in robots: joints, mount and sphere count."""
    from stalm.motion.sphere_fit_store import robot_spheres
    from stalm.world.robot_loader import builtin_robots, load_robot

    names = builtin_robots()
    width = max(len(name) for name in names)
    for name in names:
        robot = load_robot(name)
        spheres, _ = robot_spheres(robot)
        gripper = "gripper" if robot.spec.gripper is not None else "no gripper"
        joints, kind = len(robot.arm_joints), robot.spec.mount.kind
        typer.echo(
            f"{name:{width}} {joints} joints  {kind:6}  {gripper:10}  "
            f"{spheres.total} spheres  {robot.urdf_path.name}"
        )


def _mount_lines(robot: Robot, carry_radius: float | None, fits: bool | None) -> list[str]:
    from stalm.world.robot_description import MobileMount

    mount = robot.spec.mount
    if not isinstance(mount, MobileMount):
        x, y, z = mount.xyz
        return [f"mount     fixed: base link at ({x:g}, {y:g}, {z:g}) m, yaw {mount.yaw:g} rad"]
    low, high = mount.lift_range
    where = "inside" if fits else "OUTSIDE"
    return [
        f"mount     mobile: disc base r {mount.base_radius:g} m, h {mount.base_height:g} m; arm "
        f"{mount.arm_mount_forward:g} m ahead on a lift {low:g}-{high:g} m (carry "
        f"{mount.carry_lift:g} m)",
        f"          base: {mount.base_speed:g} m/s, {mount.base_acceleration:g} m/s², turn "
        f"{mount.base_turn_rate:g} rad/s, {mount.base_turn_acceleration:g} rad/s²; lift "
        f"{mount.lift_speed:g} m/s, {mount.lift_acceleration:g} m/s²",
        f"          carry pose reaches {carry_radius:.3f} m from the base centre: {where} the "
        f"{mount.base_radius:g} m base",
    ]


@robot_app.command("check")
def check_command(
    robot_name: Annotated[
        str, typer.Argument(metavar="NAME|FILE", help="A built-in robot's name or a robot file.")
    ],
    samples: Annotated[
        int, typer.Option("--samples", help="Surface points per link the sphere check tests.")
    ] = 5000,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the reach and check draws.")] = 0,
) -> None:
    """Load a robot, derive its facts from the URDF and check its sphere model; exit 1 if the
    spheres fail to contain a sampled surface point."""
    from stalm.motion.sphere_fit import CONTACT_MARGIN
    from stalm.motion.sphere_fit_store import check_robot_spheres, robot_spheres
    from stalm.trial.result import check_seed
    from stalm.world.robot_facts import robot_facts
    from stalm.world.robot_loader import load_robot

    check_seed(seed, "--seed")
    if samples < 1:
        raise StalmError(f"--samples must be at least 1, got {samples}")
    robot = load_robot(robot_name)
    spec = robot.spec
    facts = robot_facts(robot, np.random.default_rng(seed))
    spheres, origin = robot_spheres(robot)
    check = check_robot_spheres(robot, spheres, np.random.default_rng(seed), samples)
    joints = robot.arm_joints
    lines = [
        f"robot     {spec.name}  ({robot.source})",
        f"urdf      {robot.urdf_path}",
        f"          sha256 {robot.urdf_sha256[:16]} (URDF and collision meshes)",
        *_mount_lines(robot, facts.carry_radius, facts.carry_fits),
        f"chain     {spec.base_link} -> {spec.tool_link}: {len(joints)} revolute joints"
        + (f" (+{len(robot.chain) - len(joints)} fixed)" if len(robot.chain) > len(joints) else ""),
        f"  {'joint':24} {'lower':>8} {'upper':>8} {'vel':>7} {'acc':>7} {'carry':>8}",
    ]
    for joint, (low, high), vel, acc, carry in zip(
        joints, robot.joint_limits, robot.velocity_limits, robot.acceleration_limits, spec.carry,
        strict=True,
    ):  # fmt: skip
        lines.append(f"  {joint.name:24} {low:8.4f} {high:8.4f} {vel:7.3f} {acc:7.2f} {carry:8.4f}")
    lines.append("          (rad; vel rad/s, acc rad/s²)")
    for field, text in spec.sources.items():
        lines.append(f"  {field}: {text}")
    offset = spec.tool_offset
    lines.append(f"tool      {spec.tool_link} + xyz {offset.xyz} m, rpy {offset.rpy} rad")
    if spec.gripper is None:
        lines.append("gripper   none")
    else:
        fingers = ", ".join(
            f"{name}={value:g}" for name, value in spec.gripper.finger_joints.items()
        )
        lines.append(
            f"gripper   opening {spec.gripper.opening:.4f} m (fingers' collision geometry "
            f"{facts.finger_gap:.4f} m apart when open); open: {fingers}"
        )
    lines.append(
        f"reach     {facts.reach:.3f} m from the shoulder ({joints[1].name}) to the tool frame "
        f"({facts.reach_samples} configurations)"
    )
    per_link = ", ".join(f"{link.link} {len(link.radii)}" for link in spheres.links)
    lines.append(f"spheres   {spheres.total} ({origin}, delta {spheres.delta:g} m): {per_link}")
    verdict = "pass" if check.passed else "FAIL"
    lines.append(
        f"check     {check.samples} surface points ({samples} per link + hull vertices): worst "
        f"residual {check.worst_residual * 1000:+.2f} mm at {check.worst_link} (pass: <= "
        f"{-CONTACT_MARGIN * 1000:+.1f} mm): {verdict}"
    )
    for line in lines:
        typer.echo(printable(line))
    if not check.passed:
        raise typer.Exit(1)
