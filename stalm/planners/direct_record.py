"""The record of a method that asks no task-plan proposer (EP-SayCan and Iterative-Replanning
prompt their model themselves, PDDLStream plans with Fast Downward): its JSON is its fields."""

from __future__ import annotations

from stalm.json_object import JsonObject, record_json


class DirectRecord:
    """Base of such a method's frozen-dataclass record, a
    :class:`~stalm.trial.details.MethodDetails`."""

    @property
    def proposer(self) -> None:
        return None

    def to_json(self) -> JsonObject:
        return record_json(self)
