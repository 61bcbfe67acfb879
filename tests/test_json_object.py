"""A typed record becomes the JSON its file shows: fields in order, nested records by their
own shape, tuples as lists, and only the fields named so left out while None."""

from __future__ import annotations

import json
from dataclasses import dataclass, replace

from stalm.json_object import record_json


@dataclass(frozen=True)
class InnerRecordDouble:
    name: str
    sizes: tuple[int, ...]


@dataclass(frozen=True)
class OwnShapeDouble:
    value: int

    def to_json(self) -> dict[str, object]:
        return {"written": self.value * 2}


@dataclass(frozen=True)
class OuterRecordDouble:
    step: int
    inner: InnerRecordDouble
    own: OwnShapeDouble
    kept_null: str | None
    left_out: int | None
    items: tuple[InnerRecordDouble, ...]


def test_a_record_is_written_field_by_field_in_order() -> None:
    record = OuterRecordDouble(
        3,
        InnerRecordDouble("a", (1, 2)),
        OwnShapeDouble(5),
        None,
        None,
        (InnerRecordDouble("b", ()),),
    )
    data = record_json(record, omitted_when_none={"left_out"})
    assert list(data) == ["step", "inner", "own", "kept_null", "items"]
    assert data == {
        "step": 3,
        "inner": {"name": "a", "sizes": [1, 2]},
        "own": {"written": 10},
        "kept_null": None,
        "items": [{"name": "b", "sizes": []}],
    }
    assert json.loads(json.dumps(data)) == data
    # a field named to be left out is written once it holds a value
    assert record_json(replace(record, left_out=7), omitted_when_none={"left_out"})["left_out"] == 7
