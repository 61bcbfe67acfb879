"""The batched geometric core against its PyBullet reference.

* forward kinematics and IK without PyBullet (:mod:`stalm.motion.panda`) against PyBullet's
  own link frames;
* the sphere model: no PyBullet contact on random configurations beside random boxes and cans
  goes unflagged (it is conservative);
* both colliders give the same bodies for the same motions, so the predicates (every literal,
  every sampled motion's hits) and the samplers' draws are the same with either engine.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pybullet as p
import pytest

from stalm.domain.mdp import Domain
from stalm.domain.samplers import SamplerSettings
from stalm.errors import StalmError
from stalm.geometry.transforms import quat_from_matrix
from stalm.motion import ik, panda
from stalm.motion.arm_model import PANDA_NOMINAL_ARM
from stalm.motion.colliders import BatchCollider, PyBulletCollider, make_collider
from stalm.motion.panda_spheres import fit_panda_spheres, panda_spheres
from stalm.predicates.engine import PredicateEngine
from stalm.predicates.samples import PredicateSettings
from stalm.world import robot as robot_model
from stalm.world.problem import Problem, load_problem
from stalm.world.relations import supporting_region
from stalm.world.scene import Sim

DATA = Path(__file__).parent / "data"


def _random_conf(rng: np.random.Generator) -> tuple[float, ...]:
    return tuple(float(rng.uniform(lo, hi)) for lo, hi in robot_model.ARM_JOINT_LIMITS)


def test_forward_kinematics_matches_pybullets_link_frames(problems: dict[str, Problem]) -> None:
    rng = np.random.default_rng(0)
    with Sim(problems["P2"].spec) as sim:
        for _ in range(50):
            stand = (
                float(rng.uniform(-3, 3)),
                float(rng.uniform(-3, 3)),
                float(rng.uniform(-3, 3)),
            )
            lift, q = float(rng.uniform(*robot_model.LIFT_RANGE)), _random_conf(rng)
            sim.set_arm(stand, lift, q)
            frames = panda.link_frames(panda.base_frame(robot_model.arm_mount(stand, lift)), q)
            for frame in range(1, len(panda.LINK_NAMES)):
                link = frame - 1 if frame <= 7 else frame
                state = p.getLinkState(
                    sim.bodies.arm, link, computeForwardKinematics=True, physicsClientId=sim.client
                )
                rotation = np.array(p.getMatrixFromQuaternion(state[5])).reshape(3, 3)
                assert np.allclose(frames[frame][:3, 3], state[4], atol=1e-6)
                assert np.allclose(frames[frame][:3, :3], rotation, atol=1e-6)


def test_ik_reaches_what_forward_kinematics_says(problems: dict[str, Problem]) -> None:
    """Targets made by forward kinematics from random configurations near the nominal one:
    IK reaches most, and PyBullet's own forward kinematics agrees with every solution."""
    rng = np.random.default_rng(1)
    stand = (0.0, 0.0, 0.0)
    reached = 0
    with Sim(problems["P2"].spec) as sim:
        for _ in range(40):
            lift = float(rng.uniform(0.8, 1.0))
            q = np.clip(
                np.array(PANDA_NOMINAL_ARM) + rng.normal(0, 0.4, 7),
                [lo for lo, _ in robot_model.ARM_JOINT_LIMITS],
                [hi for _, hi in robot_model.ARM_JOINT_LIMITS],
            )
            frame = panda.link_frames(panda.base_frame(robot_model.arm_mount(stand, lift)), q)[
                panda.GRASP
            ]
            target = (tuple(frame[:3, 3]), quat_from_matrix(frame[:3, :3]))
            solution = ik.refine(sim, stand, target, lift, PANDA_NOMINAL_ARM)  # type: ignore[arg-type]
            if solution is None:
                continue
            reached += 1
            sim.set_arm(stand, solution.lift, solution.arm)
            assert np.linalg.norm(np.subtract(sim.gripper_pose()[0], frame[:3, 3])) < 0.005
    assert reached >= 36


def test_the_sphere_model_misses_no_pybullet_contact(problems: dict[str, Problem]) -> None:
    model = panda_spheres()
    rng = np.random.default_rng(2)
    contacts = 0
    with Sim(problems["P2"].spec) as sim:
        c = sim.client
        shapes = [
            p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.05, 0.2, 0.02], physicsClientId=c),
            p.createCollisionShape(p.GEOM_CYLINDER, radius=0.033, height=0.12, physicsClientId=c),
        ]
        probes = [p.createMultiBody(1.0, s, -1, [0, 0, -5], physicsClientId=c) for s in shapes]
        for trial in range(1500):
            lift, q = float(rng.uniform(0.6, 1.3)), _random_conf(rng)
            sim.set_arm((0.0, 0.0, 0.0), lift, q)
            frames = panda.link_frames(panda.base_frame(robot_model.arm_mount((0, 0, 0), lift)), q)
            centres = np.einsum("nij,nj->ni", frames[model.link][:, :3, :3], model.centre)
            centres += frames[model.link][:, :3, 3]
            anchor = centres[rng.integers(len(centres))] + rng.normal(0, 0.06, 3)
            tilt = p.getQuaternionFromEuler([*rng.uniform(-0.3, 0.3, 2), rng.uniform(-3, 3)])
            probe = probes[trial % 2]
            p.resetBasePositionAndOrientation(probe, anchor.tolist(), tilt, physicsClientId=c)
            touched = {
                point[3]
                for point in p.getClosestPoints(sim.bodies.arm, probe, 0.0, physicsClientId=c)
                if point[8] < -1e-3
            }
            if not touched:
                continue
            contacts += 1
            rotation = np.array(p.getMatrixFromQuaternion(tilt)).reshape(3, 3)
            local = (centres - anchor) @ rotation
            if trial % 2 == 0:
                outside = np.maximum(np.abs(local) - [0.05, 0.2, 0.02], 0.0)
                distance = np.linalg.norm(outside, axis=1) - model.radius
            else:
                radial = np.maximum(np.hypot(local[:, 0], local[:, 1]) - 0.033, 0.0)
                axial = np.maximum(np.abs(local[:, 2]) - 0.06, 0.0)
                distance = np.hypot(radial, axial) - model.radius
            flagged = {int(model.link[i]) for i in np.flatnonzero(distance < 0)}
            frames_touched = {link + 1 if link <= 6 else link for link in touched}  # -1: link 0
            assert frames_touched <= flagged, f"trial {trial}: a contact no sphere flags"
    assert contacts > 700


MESH_CLUTTER = "meshclutter20_seed5"
"""``stalm generate --layout storeroom --objects 20 --seed 5 --objects-from pybullet_data``:
nine clutter meshes of ``random_urdfs``, two of them of more than 8 convex pieces (52 and 67:
each covered by one box in the batched engine)."""


@pytest.mark.parametrize("name", ["P2", "P5", pytest.param(MESH_CLUTTER, marks=pytest.mark.slow)])
def test_both_engines_give_the_same_predicates(problems: dict[str, Problem], name: str) -> None:
    problem = load_problem(DATA / f"{name}.yaml") if name == MESH_CLUTTER else problems[name]
    domain = Domain.create(problem)
    try:
        caches = [
            PredicateEngine(
                problem, domain.sim, domain.base_planner, PredicateSettings(engine=engine)
            ).compute(problem.initial_state)
            for engine in ("pybullet", "batched")
        ]
    finally:
        domain.close()
    reference, batched = caches
    assert batched.literals == reference.literals and batched.unreachable == reference.unreachable
    assert {k: m.hits for k, m in batched.base.items()} == {
        k: m.hits for k, m in reference.base.items()
    }
    for key, record in reference.picks.items():
        assert [m.hits for m in batched.picks[key].motions] == [m.hits for m in record.motions]
    for key, samples in reference.placements.items():
        assert [s.motion.hits for s in batched.placements[key]] == [s.motion.hits for s in samples]


def test_both_engines_draw_the_same_sampler_outcomes(problems: dict[str, Problem]) -> None:
    """ψ with either engine: the same κ (or the same failure and blockers) for every legal
    action of P2's first states, from the same seed."""
    from tests.test_behaviour_unchanged import draw_record

    rows = []
    for engine in ("pybullet", "batched"):
        domain = Domain.create(problems["P2"], sampler_settings=SamplerSettings(engine=engine))
        try:
            rows.append(draw_record(domain))
        finally:
            domain.close()
    assert rows[0] == rows[1]


def test_an_unknown_engine_is_named(problems: dict[str, Problem]) -> None:
    with pytest.raises(StalmError, match=r"predicates\.engine must be one of batched, pybullet"):
        PredicateSettings(engine="fast")  # type: ignore[arg-type]
    with pytest.raises(StalmError, match=r"samplers\.engine"):
        SamplerSettings(engine="gpu")  # type: ignore[arg-type]
    with Sim(problems["P2"].spec) as sim:
        assert isinstance(make_collider(sim, "batched"), BatchCollider)
        assert isinstance(make_collider(sim, "pybullet"), PyBulletCollider)
        with pytest.raises(ValueError, match="unknown collision engine"):
            make_collider(sim, "cuda")


@pytest.mark.slow
def test_the_shipped_sphere_model_is_what_fitting_gives() -> None:
    """``python -m stalm.motion.panda_spheres`` would write the file the package ships: the
    fit is deterministic (rays on a Fibonacci sphere, k-means from principal-axis slices)."""
    fitted, shipped = fit_panda_spheres(), panda_spheres()
    assert np.array_equal(fitted.link, shipped.link)
    assert np.allclose(fitted.centre, shipped.centre, atol=2e-6)
    assert np.allclose(fitted.radius, shipped.radius, atol=2e-6)


@pytest.mark.slow
def test_a_contact_at_the_tolerance_is_one_contact_to_both_engines() -> None:
    """The case that made the engines' literals differ at 64 objects: a can carried to the
    right of another (``stalm generate --objects 64 --goals 2 --seed 3``, placing item_05
    beside item_16) penetrates it by 1.0011 mm by their closest points and by 0.973 mm by
    Bullet's contact manifold, either side of the 1 mm tolerance. Every contact is decided by
    the closest points now, so both engines sweep the same bodies for every placement."""
    problem = load_problem(DATA / "generated64_seed3.yaml")
    domain = Domain.create(problem)
    try:
        state = problem.initial_state
        region = problem.spec.region(supporting_region(problem.spec, state.pose("item_16")) or "")
        hits = {}
        for engine in ("batched", "pybullet"):
            settings = replace(PredicateSettings(), engine=engine)
            predicates = PredicateEngine(problem, domain.sim, domain.base_planner, settings)
            domain.sim.set_state(state)
            record = predicates.samples.pick_record("item_05", state.pose("item_05"))
            assert record.grasp is not None
            samples = predicates.samples.placements(
                "item_05", record.grasp, record.yaw_offset, region
            )
            hits[engine] = [sorted(sample.motion.hits) for sample in samples]
        assert hits["batched"] == hits["pybullet"]
        assert ["item_16"] in hits["pybullet"]  # the placement whose sweep grazes item_16
    finally:
        domain.close()


def test_both_engines_resweep_a_moved_object_alike(problems: dict[str, Problem]) -> None:
    """After a PLACE the cached motions are asked again about the moved object alone
    (``sweep_near``): both engines answer alike for every motion of P2's predicates, with each
    object moved to each of its own sampled placements, and some motions do touch it."""
    from stalm.motion.sweeps import sweep_near

    problem = problems["P2"]
    domain = Domain.create(problem)
    try:
        sim = domain.sim
        engine = PredicateEngine(problem, sim, domain.base_planner, PredicateSettings())
        cache = engine.compute(problem.initial_state)
        motions = [
            *cache.base.values(),
            *(m for record in cache.picks.values() for m in record.motions),
            *(s.motion for samples in cache.placements.values() for s in samples),
        ]
        engines = [PyBulletCollider(sim), BatchCollider(sim)]
        answers: list[tuple[bool, bool]] = []
        for (obj, _), samples in sorted(cache.placements.items())[::3]:
            body = sim.bodies.objects[obj]
            radius = engine.samples.hands.extent[obj]
            for sample in samples[:2]:
                for motion in motions:
                    row = []
                    for collider in engines:
                        sim.set_state(problem.initial_state)
                        sim.place_object(obj, sample.pose)
                        row.append(
                            sweep_near(collider, motion, body, sample.pose.x, sample.pose.y, radius)
                        )
                    answers.append((row[0], row[1]))
    finally:
        domain.close()
    assert all(reference == batched for reference, batched in answers)
    assert any(reference for reference, _ in answers)
    assert not all(reference for reference, _ in answers)
