"""``stalm solve`` shows where it is while it works (issue 42, finding 3).

A 120-object solve printed nothing for five minutes, then timed out. Now a solve hands its
planner a :class:`~stalm.progress.TrialObserver`: on a terminal a progress line shows the
phase, the real step of the horizon, proposals and Concretize rounds, the predicates being
computed (n of m) and the seconds of the budget; nothing when the stream is not a terminal or
with ``--quiet``. The observer only listens: a run observed makes the plan a run not observed
makes. ``--verbose`` logs each step's decisions; a timeout says what took the time and the
setting that would help.
"""

from __future__ import annotations

import io
import json

import pytest
from rich.console import Console

import stalm.cli.solve_output as solve_output
from stalm.cli.solve_progress import SolveProgress, solve_progress
from stalm.planners.registry import build_planner
from stalm.progress import QUIET, TrialObserver, observer_of
from stalm.settings.tree import RunSettings
from stalm.trial.result import PhaseTimes
from stalm.trial.timeout_advice import timeout_advice
from tests.cli_runner import run_cli
from tests.flat_settings import settings_of


@pytest.fixture(autouse=True)
def _no_llm_env(monkeypatch: pytest.MonkeyPatch) -> None:
    for name in ("STALM_LLM", "STALM_LLM_BASE_URL", "STALM_LLM_MODEL", "OPENAI_API_KEY"):
        monkeypatch.delenv(name, raising=False)


class RecordingObserverDouble(TrialObserver):
    """Test double: keeps every event it hears, in order."""

    def __init__(self) -> None:
        self.events: list[tuple[object, ...]] = []

    def started(self, planner: str, problem: str, horizon: int, budget_s: float) -> None:
        self.events.append(("started", planner, problem, horizon, budget_s))

    def phase(self, name: str) -> None:
        self.events.append(("phase", name))

    def step(self, done: int, horizon: int) -> None:
        self.events.append(("step", done, horizon))

    def proposal(self, number: int, proposer: str) -> None:
        self.events.append(("proposal", number, proposer))

    def concretize(self, round_: int, plans: int) -> None:
        self.events.append(("concretize", round_, plans))

    def predicates(self, part: str, done: int, total: int) -> None:
        self.events.append(("predicates", part, done, total))

    def message(self, text: str) -> None:
        self.events.append(("message", text))


def test_a_planner_tells_its_observer_where_it_is_and_decides_the_same(problems) -> None:
    config = settings_of(proposer="symbolic")
    observer = RecordingObserverDouble()
    observed = build_planner("stalm", config, progress=observer).solve(problems["P2"], seed=0)
    alone = build_planner("stalm", config).solve(problems["P2"], seed=0)
    assert observed.success and observed.plan == alone.plan  # it only listens
    assert observed.states == alone.states
    # the same transitions and samples (collision checks: the first run built the roadmaps)
    assert observed.counters.transitions == alone.counters.transitions
    assert observed.counters.samples == alone.counters.samples
    kinds = [event[0] for event in observer.events]
    assert observer.events[0][:4] == ("started", "stalm", "P2", problems["P2"].horizon)
    assert ("step", 0, problems["P2"].horizon) in observer.events
    phases = {event[1] for event in observer.events if event[0] == "phase"}
    assert {"setup", "predicates", "concretize", "execution"} <= phases
    assert ("proposal", 0, "symbolic:fast-downward") in observer.events
    assert "concretize" in kinds
    picks = [e for e in observer.events if e[0] == "predicates" and e[1] == "picks"]
    total = len(problems["P2"].spec.objects)
    assert picks[0] == ("predicates", "picks", 0, total)
    assert picks[-1] == ("predicates", "picks", total, total)
    assert [e[2] for e in picks[1:-1]] == list(range(1, total + 1))  # one by one


def test_a_plain_function_still_hears_the_messages() -> None:
    said: list[str] = []
    observer = observer_of(said.append)
    observer.step(0, 20)  # structured events are not messages
    observer.message("step 0: predicates")
    assert said == ["step 0: predicates"]
    assert observer_of(None) is QUIET


def test_on_a_terminal_the_progress_line_shows_phase_step_and_predicates(problems) -> None:
    stream = io.StringIO()
    terminal = Console(file=stream, force_terminal=True, width=200)
    with solve_progress(terminal, "solving P2...") as observer:
        assert isinstance(observer, SolveProgress)
        planner = build_planner("stalm", settings_of(proposer="symbolic"), progress=observer)
        planner.solve(problems["P2"], seed=0)
        observer.phase("predicates")  # shown once more, whatever the refresh caught
        observer.predicates("picks", 3, 9)
        line = observer.line()
    shown = stream.getvalue()
    assert "P2 with stalm" in line and "step " in line and " of 20" in line and " s of " in line
    assert "computing predicates (picks 3 of 9)" in line
    assert "1 proposal" in line
    assert "P2 with stalm · step 1 of 20" in shown  # the live display drew it


def test_a_stream_that_is_not_a_terminal_gets_nothing() -> None:
    stream = io.StringIO()
    with solve_progress(Console(file=stream), "solving...") as observer:
        observer.started("stalm", "P2", 20, 60.0)
        observer.step(3, 20)
        observer.predicates("picks", 1, 9)
    assert observer is QUIET
    assert stream.getvalue() == ""


def test_quiet_shows_nothing_even_on_a_terminal() -> None:
    stream = io.StringIO()
    with solve_progress(Console(file=stream, force_terminal=True), "x", quiet=True) as observer:
        observer.step(3, 20)
    assert observer is QUIET and stream.getvalue() == ""


def _terminal_console(monkeypatch: pytest.MonkeyPatch) -> io.StringIO:
    stream = io.StringIO()
    monkeypatch.setattr(
        solve_output, "console", Console(file=stream, force_terminal=True, width=200)
    )
    return stream


def test_stalm_solve_on_a_terminal_shows_progress_and_quiet_does_not(monkeypatch) -> None:
    stream = _terminal_console(monkeypatch)
    assert run_cli(monkeypatch, "solve", "P2", "--proposer", "symbolic") == 0
    assert "P2 with stalm · step 1 of 20" in stream.getvalue()
    stream = _terminal_console(monkeypatch)
    assert run_cli(monkeypatch, "solve", "P2", "--proposer", "symbolic", "--quiet") == 0
    assert "step 1 of 20" not in stream.getvalue()


def test_stalm_solve_in_a_pipe_prints_no_progress(monkeypatch, capsys) -> None:
    assert run_cli(monkeypatch, "solve", "P2", "--proposer", "symbolic") == 0
    captured = capsys.readouterr()
    assert "step 1 of" not in captured.err + captured.out
    assert "computing predicates" not in captured.err + captured.out


def test_verbose_logs_each_step_s_decisions(monkeypatch, capsys) -> None:
    assert run_cli(monkeypatch, "solve", "P2", "--proposer", "symbolic", "--verbose") == 0
    err = " ".join(capsys.readouterr().err.split())
    assert "step 0, round 0: symbolic:fast-downward offered" in err
    assert "step 0 of 20: executes open(kitchen_door)" in err


def test_without_verbose_the_decisions_are_not_logged(monkeypatch, capsys) -> None:
    assert run_cli(monkeypatch, "solve", "P2", "--proposer", "symbolic") == 0
    assert "executes" not in capsys.readouterr().err


# ---------------------------------------------------------------------- timeouts
def test_predicates_that_took_the_time_ask_for_relevant_only() -> None:
    times = PhaseTimes(predicates=250.0, proposer=30.0, total=300.0)
    advice = timeout_advice(times, RunSettings(), objects=60)
    assert advice.phase == "predicates"
    assert advice.setting == "--set predicates.relevant_only=true"
    assert "predicates took 250.0 s (83% of the time)" in advice.text()


def test_fast_downward_that_took_the_time_on_many_objects_asks_for_relevant_only() -> None:
    times = PhaseTimes(predicates=60.0, proposer=230.0, total=300.0)
    advice = timeout_advice(times, RunSettings(), 60, asks_model=False)
    assert advice.phase == "proposer"
    assert advice.setting == "--set predicates.relevant_only=true"


def test_above_relevant_above_the_predicates_are_relevant_only_and_the_advice_moves_on() -> None:
    # 120 objects: more than predicates.relevant_above (64), so relevant-only already
    times = PhaseTimes(predicates=250.0, proposer=30.0, total=300.0)
    assert timeout_advice(times, RunSettings(), 120).setting == "--set predicates.workers=N"


def test_with_relevant_only_on_the_advice_moves_on() -> None:
    from stalm.settings.io import with_values

    settings = with_values(
        RunSettings(),
        [("predicates.relevant_only", True), ("proposer.needed_objects_only", False)],
        "test",
    )
    downward = PhaseTimes(proposer=200.0, total=300.0)
    assert timeout_advice(downward, settings, 120, asks_model=False).setting == (
        "--set proposer.needed_objects_only=true"
    )
    predicates = PhaseTimes(predicates=200.0, total=300.0)
    assert timeout_advice(predicates, settings, 120).setting == "--set predicates.workers=N"
    model = timeout_advice(downward, settings, 120, asks_model=True)
    assert "--batch" in model.setting


@pytest.mark.slow
def test_a_solve_that_times_out_says_what_took_the_time(monkeypatch, capsys, tmp_path) -> None:
    out = tmp_path / "p3.json"
    code = run_cli(monkeypatch, "solve", "P3", "--time-budget", "0.5", "--json", str(out))
    assert code == 1
    assert json.loads(out.read_text())["termination"] == "timeout"
    err = " ".join(capsys.readouterr().err.split())
    assert "timed out:" in err
    assert "try --set predicates.relevant_only=true" in err


def test_a_planner_s_own_messages_show_on_the_line() -> None:
    line = SolveProgress("P2 with pddlstream-adaptive")
    assert line.line() == "P2 with pddlstream-adaptive"
    line.message("pddlstream: searching the optimistic task")  # a planner with no trial events
    assert line.line() == "pddlstream: searching the optimistic task"
    line.started("saycan", "P2", 20, 300.0)
    line.message("scoring 12 skills")
    assert line.line().endswith("scoring 12 skills")


def test_the_noisy_proposer_over_fast_downward_is_advised_as_fast_downward() -> None:
    from stalm.planners.registry import asks_model
    from stalm.settings.io import with_overrides

    settings = with_overrides(RunSettings(), ["proposer.kind=noisy"])
    asked = asks_model("stalm", settings)
    assert asked is False  # the noisy proposer corrupts Fast Downward's plans: no model
    advice = timeout_advice(PhaseTimes(proposer=230.0, total=300.0), settings, 120, asked)
    assert "model" not in advice.why and "--batch" not in advice.setting
