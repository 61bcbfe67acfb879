"""How fast, and how parseable, is the embedded model on a real task-planning prompt?

``python benchmarks/bench_llm.py [--prompt-file FILE] [--model smollm2] [--n 5] ...``

The default prompt is the paper's Figure 13 (P5), transcribed in
``benchmarks/data/p5_prompt_figure13.txt``; any file with the same ``**System prompt**`` /
``**User prompt**`` layout works, and a file without those markers is taken as the user prompt
under the paper's system message. The problem's names (for the output constraint and the parse
check) are read from the prompt's ``(:objects ...)`` line.

It prints: prompt tokens, model load time, time to the first reply, time for a batch of N with
and without the output constraint, tokens per second, the parse rate of each batch (replies
that :func:`stalm.llm.reply_parser.parse_reply` reads cleanly, and replies with a non-empty
plan), and how much evaluating the prompt once per batch saves against evaluating it for every
sample. Numbers only; nothing is asserted, because timings depend on the machine.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import re
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from stalm.domain.vocabulary import Vocabulary
from stalm.llm.backends import EmbeddedBackend, LLMRequest, LLMResponse
from stalm.llm.constraints import build_constraint

DEFAULT_PROMPT = Path(__file__).parent / "data" / "p5_prompt_figure13.txt"
PAPER_SYSTEM = (
    "You are an expert proficient in PDDL and planning actions for a problem. Your response "
    "should follow this template:\n## Possible Challenges for unachieved goals based on current "
    "state ##\n\n## Plan for unachieved goals ## plan = [('action_type', 'args_1', 'args_2',...), ]"
)
_OBJECT = re.compile(r"([A-Za-z0-9_]+) - (movable_object|openable|region)\b")


def split_prompt(text: str) -> tuple[str, str]:
    """(system, user) from a prompt file in Figure 13's layout, or (paper system, text)."""
    if "**System prompt**" in text and "**User prompt**" in text:
        system_part, user_part = text.split("**User prompt**", 1)
        system = system_part.split("**System prompt**", 1)[1]
        return system.strip(), user_part.strip()
    return PAPER_SYSTEM, text.strip()


def vocabulary_from_prompt(user: str) -> Vocabulary:
    """The problem's names from its ``(:objects ...)`` line (PDDL-style typed list)."""
    objects_line = next((line for line in user.splitlines() if "(:objects" in line), "")
    kinds: dict[str, list[str]] = {"movable_object": [], "region": [], "openable": []}
    for name, kind in _OBJECT.findall(objects_line):
        kinds[kind].append(name)
    return Vocabulary(
        movables=tuple(kinds["movable_object"]),
        regions=tuple(kinds["region"]),
        doors=tuple(kinds["openable"]),
    )


def parse_checker(vocabulary: Vocabulary) -> tuple[str, Callable[[str], tuple[bool, bool]]]:
    """(how, check): check(text) -> (parsed cleanly, has a non-empty plan)."""
    try:
        from stalm.llm.reply_parser import parse_reply
    except ImportError:  # the parser is another module's job; fall back to a shape check
        pattern = re.compile(r"plan\s*=\s*\[\s*\(.*\)\s*,?\s*\]", re.DOTALL)

        def regex_check(text: str) -> tuple[bool, bool]:
            found = bool(pattern.search(text))
            return found, found

        return "regex shape check (stalm.llm.reply_parser missing)", regex_check

    def parser_check(text: str) -> tuple[bool, bool]:
        parsed = parse_reply(text, vocabulary)
        return parsed.reason is None, bool(parsed.plan)

    return "stalm.llm.reply_parser.parse_reply", parser_check


@dataclass(frozen=True)
class BatchStats:
    """What one or more batches cost and how many of their replies parse."""

    label: str
    samples: int
    wall_s: float
    completion_tokens: int
    clean: int
    with_plan: int
    truncated: int
    decode_tokens_per_s: float

    def row(self) -> str:
        per_batch = self.wall_s / max(1, self.samples) * 5
        return (
            f"{self.label:<14} {self.samples:>3} samples  {self.wall_s:7.1f} s "
            f"(~{per_batch:5.1f} s per 5)  {self.completion_tokens:>5} tokens  "
            f"{self.completion_tokens / self.wall_s:6.1f} tok/s overall  "
            f"{self.decode_tokens_per_s:6.1f} tok/s decoding  "
            f"clean parse {self.clean}/{self.samples}  plan {self.with_plan}/{self.samples}  "
            f"cut by max_tokens {self.truncated}"
        )


def batch_stats(
    label: str,
    responses: Sequence[LLMResponse],
    wall_s: float,
    check: Callable[[str], tuple[bool, bool]],
) -> BatchStats:
    replies = [reply for response in responses for reply in response.replies]
    checks = [check(reply.text) for reply in replies]
    # Samples after the first of a batch start from the evaluated prompt: their rate is decoding.
    later = [reply for response in responses for reply in response.replies[1:]]
    decode_rate = (
        sum(r.completion_tokens for r in later) / sum(r.latency_s for r in later) if later else 0.0
    )
    return BatchStats(
        label=label,
        samples=len(replies),
        wall_s=wall_s,
        completion_tokens=sum(r.completion_tokens for r in replies),
        clean=sum(clean for clean, _ in checks),
        with_plan=sum(plan for _, plan in checks),
        truncated=sum(r.finish_reason == "length" for r in replies),
        decode_tokens_per_s=decode_rate,
    )


def timed(backend: EmbeddedBackend, request: LLMRequest) -> tuple[LLMResponse, float]:
    """The response and the wall time it took."""
    started = time.perf_counter()
    response = backend.complete(request)
    return response, time.perf_counter() - started


def run(
    prompt_text: str,
    model: str = "smollm2",
    n: int = 5,
    batches: int = 2,
    max_tokens: int = 400,
    seed: int = 0,
    threads: int | None = None,
    compare_reuse: bool = True,
    show: int = 1,
) -> dict[str, Any]:
    """Measure the embedded ``model`` on ``prompt_text``; print and return the numbers."""
    system, user = split_prompt(prompt_text)
    vocabulary = vocabulary_from_prompt(user)
    how, check = parse_checker(vocabulary)
    backend = EmbeddedBackend(model, n_threads=threads)
    print(f"model: {backend.model}  ({backend.model_path})")
    print(
        f"vocabulary: {len(vocabulary.movables)} movables, {len(vocabulary.regions)} regions, "
        f"{len(vocabulary.doors)} doors; parse check: {how}"
    )

    started = time.perf_counter()
    prompt_tokens = len(backend.prompt_tokens(system, user))  # loads the model too
    load_s = time.perf_counter() - started
    print(f"prompt tokens: {prompt_tokens}   model load + tokenize: {load_s:.2f} s")

    def request(k: int, constrained: bool, count: int = n) -> LLMRequest:
        return LLMRequest(
            system=system,
            user=user,
            n=count,
            temperature=1.0,
            max_tokens=max_tokens,
            seed=seed + 1000 * k,
            constraint=build_constraint(vocabulary) if constrained else None,
        )

    first, first_s = timed(backend, request(0, False, 1))
    reply = first.replies[0]
    print(f"first reply: {first_s:.2f} s ({reply.completion_tokens} tokens, {reply.finish_reason})")

    results: dict[str, Any] = {
        "model": backend.model,
        "prompt_tokens": prompt_tokens,
        "load_s": load_s,
        "first_reply_s": first_s,
        "first_reply_tokens": reply.completion_tokens,
    }
    examples: dict[str, list[str]] = {}
    for constrained in (False, True):
        label = "constrained" if constrained else "unconstrained"
        responses, walls = [], []
        for k in range(batches):
            response, wall = timed(backend, request(k + 1, constrained))
            responses.append(response)
            walls.append(wall)
        stats = batch_stats(label, responses, sum(walls), check)
        print(stats.row())
        print(
            f"{'':<14} batch of {n}: "
            + ", ".join(f"{w:.1f} s" for w in walls)
            + f" (median {statistics.median(walls):.1f} s)"
        )
        results[label] = {
            **stats.__dict__,
            "batch_walls_s": walls,
        }
        examples[label] = [r.text for r in responses[0].replies[:show]]

    if compare_reuse:
        # The same N samples with the prompt evaluated for every sample (n separate requests),
        # against the backend's one evaluation per batch.
        shared, shared_s = timed(backend, request(99, True))
        separate_s = 0.0
        for i in range(n):
            single = dataclasses.replace(request(99, True), n=1, seed=seed + 99_000 + i)
            separate_s += timed(backend, single)[1]
        same = (
            shared.texts[0]
            == backend.complete(dataclasses.replace(request(99, True), n=1)).texts[0]
        )
        print(
            f"prompt reuse: batch of {n} with one prompt evaluation {shared_s:.1f} s, "
            f"with {n} evaluations {separate_s:.1f} s; sample 0 reproducible alone: {same}"
        )
        results["reuse"] = {"shared_s": shared_s, "separate_s": separate_s, "reproducible": same}

    for label, texts in examples.items():
        for text in texts:
            print(f"\n--- example {label} reply ---\n{text.strip()}")
    return results


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--prompt-file", type=Path, default=DEFAULT_PROMPT)
    parser.add_argument("--model", default="smollm2", help="embedded model key or .gguf path")
    parser.add_argument("--n", type=int, default=5, help="samples per batch (paper: 5)")
    parser.add_argument("--batches", type=int, default=2, help="batches per setting")
    parser.add_argument("--max-tokens", type=int, default=400)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=None)
    parser.add_argument("--no-reuse-comparison", action="store_true")
    parser.add_argument("--json", type=Path, default=None, help="also write the numbers here")
    args = parser.parse_args(argv)
    results = run(
        args.prompt_file.read_text(encoding="utf-8"),
        model=args.model,
        n=args.n,
        batches=args.batches,
        max_tokens=args.max_tokens,
        seed=args.seed,
        threads=args.threads,
        compare_reuse=not args.no_reuse_comparison,
    )
    if args.json:
        args.json.write_text(json.dumps(results, indent=2) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
