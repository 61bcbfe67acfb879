"""The paper's experiments as lists of trials: Table 2, Table 3, Table 4 and Figure 5; and
this implementation's: ``scale`` (planners on a suite of generated problems by size), Table 3
with the noisy proposer at several error rates (``table3 --proposer noisy --rates ...``), and
``additions`` (STaLM on the noisy proposer with each of this implementation's additions to
the tree left out alone).

An :class:`ExperimentPlan` fixes the arms (rows), problems (columns), trial count, master seed
and budgets; :func:`trial_specs` expands it into one :class:`TrialSpec` per (arm, problem,
trial). Budgets are the problem files' (the paper's 300 s for P1, P2, P4 and 600 s for P3, P5,
P6) times ``budget_scale``, unless ``time_budget_s`` fixes one for all.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

from stalm.errors import StalmError
from stalm.experiments.noise_report import noisy_label
from stalm.experiments.results_log import MAX_RECORD_SECONDS
from stalm.experiments.trials import Arm, TrialSpec, check_problem_name, derive_seed
from stalm.llm.prompt import PromptOptions
from stalm.planners.registry import PROPOSING, planner_entry
from stalm.settings.io import with_values
from stalm.settings.tree import ProposerSection, RunSettings

EXPERIMENTS = ("table2", "table3", "table4", "figure5", "scale", "additions")
SCALE_PLANNERS = ("stalm-symbolic", "uct", "pddlstream-adaptive")
"""``scale``'s rows unless ``--planners`` names others: no model needed."""
TABLE2_PLANNERS = (
    "uct",
    "uct-hcount",
    "pddlstream-adaptive",
    "ep-saycan",
    "iterative-replanning",
    "llm-mcts",
    "stalm",
)
AUTHORS_SETTINGS: dict[str, object] = {
    "execution.reuse_tree": True,
    "execution.rule": "best_q",
    "rewards.goal_atom_lost": 0.0,
    "execution.kappa_tries": 3,
    "execution.feedback": False,
    "execution.backtracks": 0,
}
"""How the authors' code ran every method, which made the paper's numbers: the executed
child's subtree kept between steps, the highest-Q root action executed, no reward taken
back when an action undoes a goal conjunct, κ drawn up to 3 times per task-plan step, no
geometric feedback and no backtracking in Concretize. The rows named after the paper's
methods run with these; this implementation's additions (the tree's defaults: the
'progress' rule, -3 for an undone conjunct, feedback and backtracking with the symbolic
proposer) get rows of their own, named with a ``+``."""
PAPER_ROWS = (
    "stalm",
    "stalm-no-uct",
    "uct",
    "uct-hcount",
    "ep-saycan",
    "iterative-replanning",
    "llm-mcts",
)
"""The rows of the paper's Tables 2 and 3, each run as the authors ran it."""
PLUS_ROWS = ("stalm", "stalm-no-uct", "uct", "uct-hcount", "llm-mcts")
"""Methods whose ``NAME+`` row runs them with this implementation's additions."""
ARM_ALIASES: dict[str, tuple[str, dict[str, object]]] = {
    **{name: (name, AUTHORS_SETTINGS) for name in PAPER_ROWS},
    **{f"{name}+": (name, {}) for name in PLUS_ROWS},
    "stalm-symbolic": ("stalm", {"proposer.kind": "symbolic"}),
    "stalm-feedback": ("stalm", {"execution.feedback": True}),
}
"""Row names and the planner and settings each runs: the paper's rows with
:data:`AUTHORS_SETTINGS`, their ``+`` rows with the tree's defaults (what ``stalm solve``
runs), STaLM with the Fast Downward proposer (no model at all; geometric feedback on, and the
other additions), and STaLM with a model and geometric feedback (beyond the paper). An arm's
own settings override the command's (``--settings``, ``--set``)."""
PAPER_TRIALS = 50
ALL_PROBLEMS = ("P1", "P2", "P3", "P4", "P5", "P6")
NOISY_TABLE3_ROWS = ("stalm", "stalm-no-uct", "uct")
"""Table 3's rows with the noisy proposer: STaLM and STaLM w/o UCT at each error rate, and
UCT (no task plans at all) once, as the paper's rows run (:data:`AUTHORS_SETTINGS`)."""
ADDITIONS_PROBLEMS = ("P3", "P4", "P5", "P6")
LEFT_OUT: dict[str, dict[str, object]] = {
    "w/o tree reuse": {"execution.reuse_tree": False},
    "w/o progress rule": {"execution.rule": "best_q"},
    "w/o -3 for an undone conjunct": {"rewards.goal_atom_lost": 0.0},
    "w/o kappa retries": {"execution.kappa_tries": 1},
}
"""``additions``: each of this implementation's additions to the tree, left out alone (the
authors' way or Algorithm 2's), by the words its row's label ends with."""


@dataclass(frozen=True)
class ExperimentPlan:
    """What one ``stalm experiment`` command runs."""

    name: str
    arms: tuple[Arm, ...]
    problems: tuple[str, ...] = ALL_PROBLEMS
    trials: int = PAPER_TRIALS
    master_seed: int = 0
    budget_scale: float = 1.0
    time_budget_s: float | None = None
    problem_fields: dict[str, dict[str, object]] = field(default_factory=dict)
    """Fields each problem's records carry besides the usual ones (a suite's name and the
    problem's number of objects), by problem as ``problems`` names it."""
    problem_digests: dict[str, str] = field(default_factory=dict)
    """The SHA-256 each problem file's text must have (a suite's index records them), by
    problem as ``problems`` names it: checked on the very text the trials run."""

    def __post_init__(self) -> None:
        if self.trials < 1:
            raise StalmError(f"--trials must be at least 1, got {self.trials}")
        if not (math.isfinite(self.budget_scale) and self.budget_scale > 0):
            raise StalmError(f"--budget-scale must be a positive number, got {self.budget_scale}")
        if self.time_budget_s is not None and not (
            math.isfinite(self.time_budget_s) and self.time_budget_s > 0
        ):
            raise StalmError(
                f"--time-budget must be a positive number of seconds, got {self.time_budget_s}"
            )
        if not self.arms:
            raise StalmError(f"experiment {self.name} has no planners to run")


def arm_for(name: str, base: RunSettings, label: str | None = None) -> Arm:
    """The arm a ``--planners`` entry names (a planner or an alias such as stalm-symbolic)."""
    planner, changes = ARM_ALIASES.get(name, (name, {}))
    planner_entry(planner)  # an unknown name fails here, naming the choices
    return Arm(label or name, planner, with_values(base, changes.items(), f"row {name}"))


def build_plan(
    name: str,
    *,
    planners: tuple[str, ...] | None = None,
    problems: tuple[str, ...] | None = None,
    trials: int = PAPER_TRIALS,
    llms: tuple[str, ...] = (),
    master_seed: int = 0,
    budget_scale: float = 1.0,
    time_budget_s: float | None = None,
    base: RunSettings | None = None,
    suite: Path | None = None,
    rates: tuple[float, ...] | None = None,
) -> ExperimentPlan:
    """The arms of experiment ``name`` (see the module docstring) with the caller's choices.

    * table2: ``planners`` (default: the paper's seven rows) with one model (``llms[0]``).
    * table3: STaLM and STaLM w/o UCT for each model in ``llms`` (the paper: two models).
    * table4: STaLM with the four prompt ablations (occlusion predicates x challenges).
    * figure5: STaLM, whose records carry the failure kinds of every task plan it tried.
    * scale: ``planners`` (default :data:`SCALE_PLANNERS`) on every problem of the generated
      ``suite`` (a folder written by ``stalm generate --suite``); each record carries
      ``suite`` and ``objects``.
    * table3 with ``base.proposer.kind`` 'noisy': ``planners`` (default
      :data:`NOISY_TABLE3_ROWS`), each proposing one at every error rate of ``rates``
      (default: ``proposer.noise.rate``), labelled with it; the others once.
    * additions: STaLM as ``stalm-symbolic`` runs it but on the noisy proposer (feedback off,
      its default there) at each of ``rates``, and with each of :data:`LEFT_OUT` left out
      alone; P3-P6 unless ``problems`` says otherwise.
    """
    if name not in EXPERIMENTS:
        raise StalmError(f"unknown experiment '{name}' (available: {', '.join(EXPERIMENTS)})")
    base = base or RunSettings()
    first_llm = llms[0] if llms else base.llm.backend
    base = replace(base, llm=replace(base.llm, backend=first_llm))
    if time_budget_s is None:  # --set budget.time_budget_s is --time-budget (and one key)
        time_budget_s = base.budget.time_budget_s
    base = replace(base, budget=replace(base.budget, time_budget_s=None))
    arms: list[Arm]
    fields: dict[str, dict[str, object]] = {}
    digests: dict[str, str] = {}
    if (name == "scale") != (suite is not None):
        raise StalmError(
            "--suite DIR goes with the scale experiment (and it needs one)"
            if suite is not None
            else "the scale experiment runs a suite of generated problems: give --suite DIR"
        )
    if suite is not None:
        from stalm.generate.suite_index import read_suite

        if problems:
            raise StalmError("--problems and --suite exclude each other")
        read = read_suite(suite)
        problems = tuple(str(read.path(p)) for p in read.problems)
        fields = {
            str(read.path(p)): {"suite": read.name, "objects": p.objects} for p in read.problems
        }
        digests = {str(read.path(p)): p.sha256 for p in read.problems}
    if name == "additions":
        base = with_values(base, [("proposer.kind", "noisy")], "experiment additions")
    rates = _rates(base, rates)
    if name == "table2":
        arms = [arm_for(p, base) for p in planners or TABLE2_PLANNERS]
    elif name == "table3" and base.proposer.kind == "noisy":
        arms = _noisy_arms(base, planners or NOISY_TABLE3_ROWS, rates)
    elif name == "additions":
        arms = []
        for rate in rates:
            config = with_values(base, [("proposer.noise.rate", rate)], "--rates")
            label = noisy_label("stalm+", rate)
            arms.append(arm_for("stalm+", config, label))
            for words, changes in LEFT_OUT.items():
                left_out = with_values(config, changes.items(), f"row {label} {words}")
                arms.append(arm_for("stalm+", left_out, f"{label} {words}"))
    elif name == "table3":
        models = llms or (base.llm.backend or "embedded",)
        arms = []
        for model in models:
            config = replace(base, llm=replace(base.llm, backend=model))
            for planner in planners or ("stalm", "stalm-no-uct"):
                arms.append(arm_for(planner, config, f"{planner} [{model}]"))
    elif name == "table4":
        arms = []
        for occlusion in (True, False):
            for challenges in (True, False):
                prompt = PromptOptions(occlusion_predicates=occlusion, ask_challenges=challenges)
                label = "stalm " + ", ".join(
                    [
                        "occlusion" if occlusion else "no occlusion",
                        "challenges" if challenges else "no challenges",
                    ]
                )
                arms.append(arm_for("stalm", replace(base, prompt=prompt), label))
    elif name == "scale":
        arms = [arm_for(p, base) for p in planners or SCALE_PLANNERS]
    else:
        arms = [arm_for(p, base) for p in planners or ("stalm",)]
    labels = [arm.label for arm in arms]
    if len(set(labels)) != len(labels):
        raise StalmError(f"a planner is listed twice: {', '.join(labels)}")
    return ExperimentPlan(
        name=name,
        arms=tuple(arms),
        problems=problems or (ADDITIONS_PROBLEMS if name == "additions" else ALL_PROBLEMS),
        trials=trials,
        master_seed=master_seed,
        budget_scale=budget_scale,
        time_budget_s=time_budget_s,
        problem_fields=fields,
        problem_digests=digests,
    )


def _rates(base: RunSettings, rates: tuple[float, ...] | None) -> tuple[float, ...]:
    """The noisy proposer's error rates to run (``--rates``; default its one rate), each
    checked; a StalmError if given without the noisy proposer."""
    if base.proposer.kind != "noisy":
        if rates:
            raise StalmError("--rates goes with the noisy proposer: add --proposer noisy")
        return ()
    if not rates:
        return (base.proposer.noise.rate,)
    for rate in rates:
        if not (math.isfinite(rate) and 0.0 <= rate <= 1.0):
            raise StalmError(f"--rates: an error rate must be in [0, 1], got {rate}")
    if len(set(rates)) != len(rates):
        raise StalmError(f"--rates lists a rate twice: {', '.join(f'{r:g}' for r in rates)}")
    return rates


def _noisy_arms(base: RunSettings, rows: tuple[str, ...], rates: tuple[float, ...]) -> list[Arm]:
    """Each row that takes task plans from the proposer at every rate, labelled with it (and
    with the model the noisy proposer wraps, if it wraps one); any other row once, with the
    default proposer section, so its record is not mistaken for the noisy proposer's."""
    model = base.llm.backend or "embedded"
    suffix = f" [{model}]" if base.proposer.noise.inner == "llm" else ""
    arms: list[Arm] = []
    for row in rows:
        if ARM_ALIASES.get(row, (row, {}))[0] not in PROPOSING:
            arms.append(arm_for(row, replace(base, proposer=ProposerSection())))
            continue
        for rate in rates:
            config = with_values(base, [("proposer.noise.rate", rate)], "--rates")
            arms.append(arm_for(row, config, noisy_label(row, rate) + suffix))
    return arms


def trial_specs(plan: ExperimentPlan) -> list[TrialSpec]:
    """Every trial of ``plan``, trial-major: the first trial of every (problem, arm) comes
    before any second trial, so a run stopped early still covers the whole table."""
    loaded = {name: check_problem_name(name) for name in plan.problems}
    for name, digest in plan.problem_digests.items():
        if hashlib.sha256(loaded[name][1].encode()).hexdigest() != digest:
            raise StalmError(
                f"{name}: differs from the suite's index (edited after it was generated?): "
                "make the suite again (stalm generate --suite ... --replace)"
            )
    specs = []
    for trial in range(plan.trials):
        for problem in plan.problems:
            canonical, text, problem_budget, folder = loaded[problem]
            budget = plan.time_budget_s or problem_budget
            if budget * plan.budget_scale > MAX_RECORD_SECONDS:
                raise StalmError(
                    f"{problem}: a time budget of {budget * plan.budget_scale:g} s is more than "
                    f"a record holds ({MAX_RECORD_SECONDS:g} s)"
                )
            for arm in plan.arms:
                specs.append(
                    TrialSpec(
                        experiment=plan.name,
                        arm=arm,
                        problem=canonical,
                        problem_yaml=text,
                        trial=trial,
                        seed=derive_seed(plan.master_seed, canonical, trial),
                        time_budget_s=round(budget * plan.budget_scale, 3),
                        fields=tuple(plan.problem_fields.get(problem, {}).items()),
                        problem_dir=folder,
                    )
                )
    return specs
