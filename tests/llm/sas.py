"""Run Fast Downward's translator on our PDDL and interpret its SAS+ output, for tests.

The translator (PyPI ``fast-downward-translate``, run as ``python -m fast_downward.translate
DOMAIN PROBLEM --sas-file OUT``) parses, normalises and grounds the PDDL, so a domain it accepts
is real PDDL. To check that the PDDL also *means* the right thing, this module reads the SAS+
task it writes (variables, initial state, goal, operators with conditional effects, axiom
rules) and evaluates it: which operators apply in a state and, for tiny problems, a shortest
plan by breadth-first search. The SAS+ format is documented with Fast Downward
(translator output format); only the parts our domain produces are read.
"""

from __future__ import annotations

import subprocess
import sys
from collections import deque
from dataclasses import dataclass
from pathlib import Path

State = tuple[int, ...]
Condition = tuple[int, int]


@dataclass(frozen=True)
class Effect:
    conditions: tuple[Condition, ...]
    var: int
    pre: int
    post: int


@dataclass(frozen=True)
class Operator:
    name: tuple[str, ...]
    prevail: tuple[Condition, ...]
    effects: tuple[Effect, ...]


@dataclass(frozen=True)
class Rule:
    conditions: tuple[Condition, ...]
    var: int
    value: int


@dataclass(frozen=True)
class SasTask:
    layers: tuple[int, ...]
    init: State
    goal: tuple[Condition, ...]
    operators: tuple[Operator, ...]
    rules: tuple[Rule, ...]

    def operator_names(self) -> set[tuple[str, ...]]:
        return {operator.name for operator in self.operators}

    def with_axioms(self, state: State) -> State:
        """Derived variables reset to their defaults, then rules applied layer by layer."""
        values = [
            self.init[var] if layer >= 0 else value
            for var, (layer, value) in enumerate(zip(self.layers, state, strict=True))
        ]
        for layer in sorted({layer for layer in self.layers if layer >= 0}):
            changed = True
            while changed:
                changed = False
                for rule in self.rules:
                    if self.layers[rule.var] != layer or values[rule.var] == rule.value:
                        continue
                    if all(values[var] == value for var, value in rule.conditions):
                        values[rule.var] = rule.value
                        changed = True
        return tuple(values)

    def applicable(self, state: State) -> list[Operator]:
        full = self.with_axioms(state)
        return [
            operator
            for operator in self.operators
            if all(full[var] == value for var, value in operator.prevail)
            and all(effect.pre in (-1, full[effect.var]) for effect in operator.effects)
        ]

    def apply(self, state: State, operator: Operator) -> State:
        full = self.with_axioms(state)
        values = list(state)
        for effect in operator.effects:
            if all(full[var] == value for var, value in effect.conditions):
                values[effect.var] = effect.post
        return tuple(values)

    def is_goal(self, state: State) -> bool:
        full = self.with_axioms(state)
        return all(full[var] == value for var, value in self.goal)

    def shortest_plan(self, max_states: int = 200_000) -> list[tuple[str, ...]] | None:
        """Breadth-first search; None when the goal is unreachable (within ``max_states``)."""
        parents: dict[State, tuple[State, tuple[str, ...]] | None] = {self.init: None}
        queue = deque([self.init])
        while queue and len(parents) < max_states:
            state = queue.popleft()
            if self.is_goal(state):
                plan: list[tuple[str, ...]] = []
                link = parents[state]
                while link is not None:
                    state, name = link
                    plan.append(name)
                    link = parents[state]
                return plan[::-1]
            for operator in self.applicable(state):
                successor = self.apply(state, operator)
                if successor not in parents:
                    parents[successor] = (state, operator.name)
                    queue.append(successor)
        return None


def translate(domain: str, problem: str, workdir: Path) -> SasTask:
    """Write the PDDL, run the translator (failing the test on an error) and read its output."""
    domain_file, problem_file = workdir / "domain.pddl", workdir / "problem.pddl"
    sas_file = workdir / "output.sas"
    domain_file.write_text(domain)
    problem_file.write_text(problem)
    command = [
        sys.executable,
        "-m",
        "fast_downward.translate",
        str(domain_file),
        str(problem_file),
        "--sas-file",
        str(sas_file),
    ]
    result = subprocess.run(command, capture_output=True, text=True, timeout=60, check=False)
    assert result.returncode == 0, f"translator failed:\n{result.stdout}\n{result.stderr}"
    return read_sas(sas_file.read_text())


def read_sas(text: str) -> SasTask:
    lines = iter(text.splitlines())

    def ints() -> list[int]:
        return [int(word) for word in next(lines).split()]

    def conditions(count: int) -> tuple[Condition, ...]:
        pairs = []
        for _ in range(count):
            var, value = ints()
            pairs.append((var, value))
        return tuple(pairs)

    layers: list[int] = []
    init: State = ()
    goal: tuple[Condition, ...] = ()
    operators: list[Operator] = []
    rules: list[Rule] = []
    for line in lines:
        if line == "begin_variable":
            next(lines)  # name
            layers.append(ints()[0])
        elif line == "begin_state":
            init = tuple(ints()[0] for _ in layers)
        elif line == "begin_goal":
            goal = conditions(ints()[0])
        elif line == "begin_operator":
            name = tuple(next(lines).split())
            prevail = conditions(ints()[0])
            effects = []
            for _ in range(ints()[0]):
                numbers = ints()
                count = numbers[0]
                pairs = numbers[1 : 1 + 2 * count]
                cond = tuple((pairs[i], pairs[i + 1]) for i in range(0, len(pairs), 2))
                var, pre, post = numbers[1 + 2 * count :]
                effects.append(Effect(cond, var, pre, post))
            operators.append(Operator(name, prevail, tuple(effects)))
        elif line == "begin_rule":
            cond = conditions(ints()[0])
            var, _old, new = ints()
            rules.append(Rule(cond, var, new))
    return SasTask(tuple(layers), init, goal, tuple(operators), tuple(rules))
