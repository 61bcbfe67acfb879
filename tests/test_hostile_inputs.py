"""Property tests: generated problem files, settings files, replies, result lines, state files,
plan steps and forged executed plans thrown at the loaders, the parser and the replay (issues
16, 30 and 46).

Whatever the input, each either gives a valid value or raises one clean
:class:`~stalm.errors.StalmError`: no other exception escapes, and each call ends in bounded
time (hypothesis' ``deadline``). Inputs are built from a valid example mutated at random
(fields replaced by hostile values: NaN, infinity, huge or negative numbers, markup, control
codes, wrong types, deep nesting) and from raw bytes.
"""

from __future__ import annotations

import copy
import functools
import json
import math
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from stalm.errors import StalmError
from stalm.settings.io import from_mapping, to_dict, with_file
from stalm.settings.tree import RunSettings
from stalm.world.problem import Problem, load_problem

FAST = settings(
    max_examples=60,
    deadline=2000,  # ms per example: every loader here is linear and small
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
P2 = load_problem("P2")
P2_DATA = yaml.safe_load(Path(P2.source).read_text())
STATE_JSON = P2.initial_state.to_json()
GENUINE_RESULT = json.loads(
    (Path(__file__).parent / "planners" / "data" / "p2_result.json").read_text()
)

HOSTILE_TEXT = st.sampled_from(
    ["", " ", "[/]", "[bold]x", "\x1b[2J", "\x00", "\u202e", ")(", "a b", "é", "x" * 70, "NaN"]
)
HOSTILE_NUMBER = st.one_of(
    st.sampled_from([math.nan, math.inf, -math.inf, 0, -1, 1e308, -1e-308, 2**70]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(),
)
LEAF = st.one_of(HOSTILE_TEXT, HOSTILE_NUMBER, st.booleans(), st.none())
HOSTILE_VALUE = st.recursive(
    LEAF,
    lambda inner: st.one_of(
        st.lists(inner, max_size=4), st.dictionaries(HOSTILE_TEXT, inner, max_size=3)
    ),
    max_leaves=8,
)


def _paths(value: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Every path to a node of a JSON-like value."""
    found = [prefix]
    if isinstance(value, dict):
        for key, item in value.items():
            found += _paths(item, (*prefix, key))
    elif isinstance(value, list):
        for index, item in enumerate(value):
            found += _paths(item, (*prefix, index))
    return found


@st.composite
def mutated(draw: st.DrawFn, original: Any, max_changes: int = 3) -> Any:
    """``original`` with a few nodes replaced by hostile values (or removed)."""
    data = copy.deepcopy(original)
    paths = [p for p in _paths(data) if p]
    for _ in range(draw(st.integers(1, max_changes))):
        path = draw(st.sampled_from(paths))
        parent = data
        try:
            for key in path[:-1]:
                parent = parent[key]
            if draw(st.booleans()) and isinstance(parent, dict):
                parent.pop(path[-1], None)
            else:
                parent[path[-1]] = draw(HOSTILE_VALUE)
        except (KeyError, IndexError, TypeError):
            continue  # an earlier change removed or replaced this path
    return data


def _deep(depth: int) -> str:
    return "[" * depth + "]" * depth


ALIAS_BOMB = "".join(
    f"l{i}: &l{i} [" + ", ".join([f"*l{i - 1}"] * 9) + "]\n" for i in range(1, 12)
).replace("*l0", "0")
"""Eleven levels of nine aliases each: 9**11 values once expanded, in about 500 bytes."""


def raw_yaml(*specific: str) -> st.SearchStrategy[bytes | str]:
    """Raw file contents: random bytes or text, or a hostile YAML document (the common ones
    and ``specific``)."""
    common = ["!!python/object:os.system {}\n", ALIAS_BOMB, _deep(5000)]
    return st.one_of(
        st.binary(max_size=300), st.text(max_size=300), st.sampled_from([*common, *specific])
    )


def _write_yaml(path: Path, data: Any) -> bool:
    """``data`` dumped as YAML at ``path``; False when it cannot be dumped."""
    try:
        path.write_text(yaml.safe_dump(data, allow_unicode=True))
    except yaml.YAMLError:
        return False
    return True


def _write_raw(path: Path, raw: bytes | str) -> None:
    if isinstance(raw, str):
        path.write_text(raw, encoding="utf-8", errors="surrogatepass")
    else:
        path.write_bytes(raw)


# ---------------------------------------------------------------------------------------------
# problem files


@FAST
@given(data=mutated(P2_DATA))
def test_mutated_problem_files(tmp_path_factory: pytest.TempPathFactory, data: Any) -> None:
    path = tmp_path_factory.mktemp("problem") / "p.yaml"
    if _write_yaml(path, data):
        _load_problem_or_stalm_error(path)


@FAST
@given(
    raw=raw_yaml(
        "a: &x [1]\nb: [*x, *x]\n",
        "a: &a [*a]\n",
        "name: 2001-02-30\n",
        "{" * 200,
        "a: " + "[" * 100 + "]" * 100,
    )
)
def test_raw_problem_files(tmp_path_factory: pytest.TempPathFactory, raw: bytes | str) -> None:
    path = tmp_path_factory.mktemp("problem") / "p.yaml"
    _write_raw(path, raw)
    _load_problem_or_stalm_error(path)


def _load_problem_or_stalm_error(path: Path) -> None:
    try:
        problem = load_problem(path)
    except StalmError as error:
        assert str(error)
        return
    # a problem that loads is usable: its initial state, goal and hash exist
    assert isinstance(problem, Problem)
    assert problem.initial_state.object_names
    assert problem.goal and len(problem.content_hash) == 16


# ---------------------------------------------------------------------------------------------
# settings files (``--settings``): the problem files' guards (issue 30, item 9)

SETTINGS_DATA = to_dict(RunSettings())


@FAST
@given(data=mutated(SETTINGS_DATA))
def test_mutated_settings_files(tmp_path_factory: pytest.TempPathFactory, data: Any) -> None:
    path = tmp_path_factory.mktemp("settings") / "s.yaml"
    if _write_yaml(path, data):
        _settings_or_stalm_error(path)


@FAST
@given(
    raw=raw_yaml(
        "search: &x {c: 50}\nexecution: *x\n",
        "search: &a [*a]\n",
        "search: {c: .nan}\n",
        "budget: {time_budget_s: 1e999}\n",
        "proposer: {noise: {rate: [1, 2]}}\n",
    )
)
def test_raw_settings_files(tmp_path_factory: pytest.TempPathFactory, raw: bytes | str) -> None:
    path = tmp_path_factory.mktemp("settings") / "s.yaml"
    _write_raw(path, raw)
    _settings_or_stalm_error(path)


def _settings_or_stalm_error(path: Path) -> None:
    try:
        loaded = with_file(RunSettings(), path)
    except StalmError as error:
        assert str(error) and "\n" not in str(error).strip(), "one line"
        return
    # settings that load are a whole tree that writes back to what it read
    assert isinstance(loaded, RunSettings)
    assert from_mapping(to_dict(loaded), "round trip") == loaded


# ---------------------------------------------------------------------------------------------
# replies


REPLY_PIECES = st.sampled_from(
    [
        "plan = [",
        "[(",
        "('pick', 'salter')",
        "('place', 'salter', 'on', 'table2')",
        "('open', 'kitchen_door')",
        "# ]",
        "```",
        "'",
        '"',
        "\\",
        "\n",
        ",",
        ")",
        "]",
        "(",
        "{",
        '{"plan": [["pick", "salter"]]}',
        "\x1b[2J",
        "[/]",
        " " * 50,
    ]
)
REPLIES = st.one_of(
    st.text(max_size=400),
    st.lists(REPLY_PIECES, max_size=200).map("".join),
    st.tuples(REPLY_PIECES, st.integers(1, 20_000)).map(lambda pair: pair[0] * pair[1]),
)


@FAST
@given(text=REPLIES)
def test_replies_parse_to_a_plan_or_a_reason(text: str) -> None:
    from stalm.domain.vocabulary import Vocabulary
    from stalm.llm.constraints import json_reply_to_plan_text
    from stalm.llm.reply_parser import parse_reply

    vocabulary = Vocabulary.from_problem(P2)
    parsed = parse_reply(text, vocabulary)
    assert parsed.plan or parsed.reason
    json.dumps(parsed.to_json())
    try:
        converted = json_reply_to_plan_text(text)
    except StalmError:
        return
    assert isinstance(converted, str)
    parse_reply(converted, vocabulary)


# ---------------------------------------------------------------------------------------------
# result lines


RECORD = {
    "key": "abc",
    "arm": "stalm",
    "problem": "P2",
    "trial": 0,
    "termination": "goal",
    "success": True,
    "time_s": 12.5,
    "time_budget_s": 30.0,
    "llm_plan_failures": {"unparseable": 2},
}
LINES = st.one_of(
    mutated(RECORD).map(lambda r: json.dumps(r).encode()),
    st.just(json.dumps(RECORD).encode()),
    st.binary(max_size=80),
    st.sampled_from([b"\xff\xfe", b"NaN", b"[]", b"{}", _deep(3000).encode(), b'{"key": 1}']),
)


@FAST
@given(lines=st.lists(LINES, max_size=12), newline_at_end=st.booleans())
def test_result_logs_load_and_report(
    tmp_path_factory: pytest.TempPathFactory, lines: list[bytes], newline_at_end: bool
) -> None:
    from stalm.experiments.report import build_table, csv_table, failure_shares, markdown_table
    from stalm.experiments.results_log import ResultsLog, read_records

    path = tmp_path_factory.mktemp("results") / "r.jsonl"
    path.write_bytes(b"\n".join(lines) + (b"\n" if newline_at_end else b""))
    loaded = read_records(path)
    table = build_table(loaded.records)
    markdown_table(table, paper=True)
    csv_table(table)
    failure_shares(loaded.records)
    log = ResultsLog(path)  # resuming: whole records kept, a partial tail set aside
    assert log.load().records == loaded.records
    assert path.read_bytes().endswith(b"\n") or not path.read_bytes()


# ---------------------------------------------------------------------------------------------
# state files and plan steps


@FAST
@given(data=st.one_of(mutated(STATE_JSON), HOSTILE_VALUE))
def test_state_files(tmp_path_factory: pytest.TempPathFactory, data: Any) -> None:
    from stalm.cli.world_commands import read_state_file

    path = tmp_path_factory.mktemp("state") / "s.json"
    path.write_text(json.dumps(data))
    try:
        state = read_state_file(path, P2)
    except StalmError:
        return
    assert set(state.object_names) == {o.name for o in P2.spec.objects}
    assert all(math.isfinite(v) for _, pose in state.poses for v in (pose.x, pose.y, pose.z))


@FAST
@given(step=mutated(GENUINE_RESULT["plan"][1]))
def test_plan_steps(step: Any) -> None:
    from stalm.domain.serialize import action_from_json

    try:
        action = action_from_json(step)
    except StalmError:
        return
    params = action.params
    assert all(math.isfinite(v) for corner in params.base_path.corners for v in corner)
    assert all(math.isfinite(v) for conf in params.arm_waypoints for v in conf)


# ---------------------------------------------------------------------------------------------
# executed plans: forged poses, joints, paths and cut motions (issue 46)
#
# Every mutant below leaves the robot's real geometry by more than any tolerance of the replay:
# a joint or the lift beyond its limits, a grasp that is no rotation or holds the object from
# beyond its size, an object turned in the hand from how it stands or is placed, a corner or a
# placement off the floor, a base path that starts or ends elsewhere than the robot stands, an
# arm motion cut so that it starts or ends elsewhere than the robot's configuration, a motion
# too long to sweep. Each must be refused at its own step: the plan is read
# (:func:`~stalm.trial.replay.read_plan`) and the step replayed from the state the genuine plan
# reaches before it, as a whole replay would.

PICKS, PLACES, EVERY_STEP = (1, 3, 5), (2, 4, 6), tuple(range(7))
HUGE = st.sampled_from([2 * math.pi, 1e5, 1e7, 1e300])
BEYOND = st.one_of(st.floats(0.002, 10.0), HUGE)
"""How far beyond a limit a forged number lies."""


@functools.cache
def _genuine_states() -> tuple[Any, ...]:
    from stalm.trial.replay import replay_result_json

    report = replay_result_json(P2, GENUINE_RESULT)
    assert report.reached_goal
    return report.states


def _limits() -> list[tuple[float, float]]:
    from stalm.world.robot import ARM_JOINT_LIMITS, LIFT_RANGE

    return [LIFT_RANGE, *ARM_JOINT_LIMITS]


def _key(step: dict[str, Any]) -> str:
    return next(k for k in ("grasp_conf", "place_conf", "handle_conf") if k in step)


def _set_everywhere(step: dict[str, Any], conf: list[float], index: int, value: float) -> None:
    """Set ``conf[index]`` in every copy of ``conf`` in the step (a waypoint that is the key
    configuration stays the key configuration)."""
    original = list(conf)
    for each in [*step["arm_waypoints"], step[_key(step)]]:
        if each == original:
            each[index] = value


@st.composite
def _forge_joint(draw: st.DrawFn, step: dict[str, Any]) -> None:
    confs = [*step["arm_waypoints"], step[_key(step)]]
    conf = draw(st.sampled_from(confs))
    index = draw(st.integers(0, 7))
    low, high = _limits()[index]
    value = high + draw(BEYOND) if draw(st.booleans()) else low - draw(BEYOND)
    _set_everywhere(step, conf, index, value)


@st.composite
def _forge_grasp(draw: st.DrawFn, step: dict[str, Any]) -> None:
    if "grasp" not in step:
        return draw(_forge_corner(step))
    if draw(st.booleans()):  # no rotation: scaled, or numbers that compose to NaN
        scale = draw(st.one_of(st.floats(1.001, 1e100), st.floats(0.0, 0.999)))
        orientation = [v * scale for v in step["grasp"]["orientation"]]
        step["grasp"]["orientation"] = draw(
            st.sampled_from([orientation, [1e300, 1e300, 0.0, 0.0], [0.0] * 4])
        )
    else:  # the object held from farther than it is big
        distance = draw(st.floats(1.0, 1e6))
        step["grasp"]["position"] = [0.0, distance, 0.0]
    return None


@st.composite
def _turn_held_object(draw: st.DrawFn, step: dict[str, Any]) -> None:
    """A pick's grasp turned about the object's own axis, or a placement's yaw turned: the
    object would jump from how it stands (or is held) to another orientation."""
    angle = draw(st.floats(0.2, 2 * math.pi - 0.2))
    if "grasp" in step:
        x, y, z, w = step["grasp"]["orientation"]
        c, s = math.cos(angle / 2), math.sin(angle / 2)  # q * (0, 0, sin, cos)
        step["grasp"]["orientation"] = [x * c + y * s, y * c - x * s, z * c + w * s, w * c - z * s]
    elif "placement" in step:
        step["placement"][3] += angle
    else:
        draw(_forge_joint(step))


@st.composite
def _forge_corner(draw: st.DrawFn, step: dict[str, Any]) -> None:
    (x0, _), (x1, _) = P2.spec.floor
    corner = draw(st.sampled_from(step["base_path"]))
    corner[0] = x1 + draw(BEYOND) if draw(st.booleans()) else x0 - draw(BEYOND)


@st.composite
def _forge_path_end(draw: st.DrawFn, step: dict[str, Any]) -> None:
    """The base path's first or last corner moved: a teleport, or standing elsewhere."""
    corner = step["base_path"][draw(st.sampled_from([0, -1]))]
    axis = draw(st.integers(0, 1))
    corner[axis] += draw(st.sampled_from([1, -1])) * draw(st.floats(0.002, 3.0))


@st.composite
def _forge_placement(draw: st.DrawFn, step: dict[str, Any]) -> None:
    if "placement" not in step:
        return draw(_forge_joint(step))
    (_, y0), (_, y1) = P2.spec.floor
    step["placement"][1] = y1 + draw(BEYOND) if draw(st.booleans()) else y0 - draw(BEYOND)
    return None


@st.composite
def _cut_waypoints(draw: st.DrawFn, step: dict[str, Any]) -> None:
    """Waypoints cut from the start, the end or both (the key configuration kept)."""
    waypoints = step["arm_waypoints"]
    key = waypoints.index(step[_key(step)])
    first = draw(st.integers(0, key))
    last = draw(st.integers(key + 1, len(waypoints)))
    cut = waypoints[first:last]
    # cutting waypoints equal to an end is no forgery: the motion still starts and ends there
    assume(max(math.dist(cut[0], waypoints[0]), math.dist(cut[-1], waypoints[-1])) > 0.01)
    step["arm_waypoints"] = cut


@st.composite
def _too_long(draw: st.DrawFn, step: dict[str, Any]) -> None:
    """Motions within every bound but too long to sweep: the base across the floor and back,
    or the arm between two extreme configurations, hundreds of times."""
    if draw(st.booleans()):
        crossings = [[-4.5, -4.5, 0.0], [4.5, 4.5, 0.0]] * draw(st.integers(400, 2000))
        step["base_path"][1:1] = crossings
    else:
        folded = list(step["arm_waypoints"][0])
        stretched = [folded[0], 2.8, 1.7, 2.8, -0.1, 2.8, 3.7, 2.8]
        step["arm_waypoints"][1:1] = [stretched, folded] * draw(st.integers(200, 600))


FORGERIES = (
    _forge_joint,
    _forge_grasp,
    _turn_held_object,
    _forge_corner,
    _forge_path_end,
    _forge_placement,
    _cut_waypoints,
    _too_long,
)


@st.composite
def forged_plans(draw: st.DrawFn) -> tuple[tuple[int, ...], list[Any]]:
    """The genuine plan with one to three of its steps forged, each once (two forgeries of one
    step could undo each other: a corner moved off the floor and back); the forged steps."""
    plan = copy.deepcopy(GENUINE_RESULT["plan"])
    steps = draw(st.lists(st.sampled_from(EVERY_STEP), min_size=1, max_size=3, unique=True))
    for index in steps:
        draw(draw(st.sampled_from(FORGERIES))(plan[index]))
    return tuple(sorted(steps)), json.loads(json.dumps(plan))


def _named_step(error: StalmError, forged: tuple[int, ...]) -> None:
    """Reading the plan refused one of the forged steps (the first whose numbers are out of
    bounds, which need not be the first forged)."""
    assert any(str(error).startswith(f"step {i + 1} of the plan: ") for i in forged), error


@FAST
@given(forged=forged_plans())
def test_forged_plans_are_refused_at_a_forged_step(
    forged: tuple[tuple[int, ...], list[Any]],
) -> None:
    from stalm.trial.replay import read_plan, replay_plan

    steps, plan = forged
    try:
        actions = read_plan(P2, plan)
    except StalmError as error:
        _named_step(error, steps)
        return
    first = steps[0]  # every forged step reads: the first fails as it is executed
    report = replay_plan(P2, _genuine_states()[first], actions[first : first + 1])
    assert not report.reached_goal and report.failed_step == 0, report.reason


@pytest.mark.slow
@settings(FAST, max_examples=400)
@given(forged=forged_plans())
def test_forged_plans_are_never_replayed_as_reached(
    forged: tuple[tuple[int, ...], list[Any]],
) -> None:
    """The whole record replayed from the problem's initial state, many more mutants."""
    from stalm.trial.replay import replay_result_json

    steps, plan = forged
    try:
        report = replay_result_json(P2, {**GENUINE_RESULT, "plan": plan})
    except StalmError as error:
        _named_step(error, steps)
        return
    assert not report.reached_goal and report.failed_step == steps[0], report.reason


def test_the_genuine_plan_is_not_refused_by_the_forgery_checks() -> None:
    """The oracle above is not vacuous: unforged, every step replays from its state."""
    from stalm.trial.replay import read_plan, replay_plan

    actions = read_plan(P2, GENUINE_RESULT["plan"])
    states = _genuine_states()
    for index, action in enumerate(actions):
        report = replay_plan(P2, states[index], [action])
        assert report.failed_step is None and report.states[-1] == states[index + 1]
