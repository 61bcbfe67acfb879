"""The paper's published numbers (Table 2), to print beside a reproduction.

Success rate over 50 trials and mean planning time (s) of the successes; None where the
paper writes t/o (no success within 300 s for P1, P2, P4 or 600 s for P3, P5, P6).
"""

from __future__ import annotations

PaperCell = tuple[float, float | None]

TABLE2: dict[str, dict[str, PaperCell]] = {
    "uct": {
        "P1": (0.02, 229.43),
        "P2": (0.8, 93.892),
        "P3": (0.0, None),
        "P4": (0.20, 122.48),
        "P5": (0.0, None),
        "P6": (0.0, None),
    },
    "uct-hcount": {
        "P1": (0.0, None),
        "P2": (0.90, 163.80),
        "P3": (0.0, None),
        "P4": (0.36, 219.67),
        "P5": (0.08, 356.65),
        "P6": (0.0, None),
    },
    "pddlstream-adaptive": {
        "P1": (0.20, 148.88),
        "P2": (0.56, 107.06),
        "P3": (0.0, None),
        "P4": (0.24, 130.27),
        "P5": (0.12, 232.97),
        "P6": (0.0, None),
    },
    "ep-saycan": {
        "P1": (0.02, 54.01),
        "P2": (0.14, 81.68),
        "P3": (0.0, None),
        "P4": (0.0, None),
        "P5": (0.0, None),
        "P6": (0.0, None),
    },
    "iterative-replanning": {
        "P1": (1.00, 64.00),
        "P2": (0.98, 94.47),
        "P3": (0.36, 260.76),
        "P4": (0.22, 163.43),
        "P5": (0.36, 163.42),
        "P6": (0.36, 128.83),
    },
    "llm-mcts": {p: (0.0, None) for p in ("P1", "P2", "P3", "P4", "P5", "P6")},
    "stalm": {
        "P1": (1.00, 31.22),
        "P2": (1.00, 54.18),
        "P3": (0.84, 241.67),
        "P4": (0.96, 148.37),
        "P5": (0.88, 233.21),
        "P6": (0.96, 165.85),
    },
}
"""Table 2 of the paper (GPT-4-turbo for every model-based method)."""
