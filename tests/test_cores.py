"""A count of processes is refused past the cores this process may use, and below one, in
one message naming the range and the value (issue 46, item 6; the commands that take a count
are tests/cli/test_process_counts.py's)."""

from __future__ import annotations

import os

import pytest

from stalm.cores import check_process_count, usable_cores
from stalm.errors import StalmError
from stalm.predicates.samples import PredicateSettings

TOO_MANY = 1000
"""More processes than any machine this runs on has cores (999 forked children once)."""


def test_the_cores_are_the_affinity_mask() -> None:
    assert usable_cores() == len(os.sched_getaffinity(0)) >= 1


@pytest.mark.parametrize("good", [1, "cores"])
def test_one_to_the_cores_are_accepted(good: object) -> None:
    count = usable_cores() if good == "cores" else good
    assert check_process_count("--workers", count) == count


@pytest.mark.parametrize("bad", [0, -1, TOO_MANY, 1.5, True, "2"])
def test_anything_else_is_refused_naming_the_range_and_the_value(bad: object) -> None:
    with pytest.raises(StalmError) as caught:
        check_process_count("--workers", bad)
    assert str(caught.value) == (
        f"--workers must be a whole number of processes from 1 to {usable_cores()} (the cores "
        f"this process may use), got {bad!r}"
    )


def test_the_setting_is_refused_past_the_cores() -> None:
    with pytest.raises(StalmError, match=r"setting predicates\.workers .* got 1000"):
        PredicateSettings(workers=TOO_MANY)
