from __future__ import annotations

import datetime
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, Self, TypeVar, cast

from attrs import define as _attrs_define
from attrs import field as _attrs_field

from ..models.job_state import JobState
from ..types import UNSET, Unset

if TYPE_CHECKING:
    from ..models.grid import Grid
    from ..models.job_distance import JobDistance
    from ..models.job_timings import JobTimings
    from ..models.problem import Problem


T = TypeVar("T", bound="Job")


@_attrs_define
class Job:
    """
    Attributes:
        id (str):
        state (JobState):
        progress (float):
        method (str):
        grid (Grid):
        created (datetime.datetime):
        timings (JobTimings):
        position (int | Unset): 1-based queue position while queued
        name (None | str | Unset):
        key_name (str | Unset): with API keys: the name of the key that submitted the job (never the key)
        distance (JobDistance | Unset): distance volumes (kind sparse-distance) and method=distance: how the distances
            were kept
        owner (str | Unset): with API keys: the tenant that owns the job and its volume (the key's tenant)
        request_id (str | Unset): the id of the request that submitted the job (its X-Request-Id, or the id the server
            gave it): on the job's log lines too
        volume_id (str | Unset):
        attempts (int | Unset): times the job was started, on either queue (more than one: its process or replica died
            during a start and it ran again; at --max-attempts it fails)
        problem (Problem | Unset): `type` is one of: https://voxd.dev/problems/invalid-mesh (422), unsupported-media-
            type (415),
            external-resource (422), too-many-triangles (422), body-too-large (413), grid-too-large (422),
            invalid-parameter (400), queue-full (429), queue-unavailable (503), not-found (404),
            not-cancelable (409), storage-full (507), storage-unavailable (503),
            engine-failure (500), shutting-down (503),
            misaligned-grids (422), wrong-volume-kind (422), empty-intersection (422), too-much-memory (422),
            timeout (408),
            busy (503), method-not-allowed (405), precondition-failed (412), uri-too-long (414),
            headers-too-large (431),
            expectation-failed (417),
            range-not-satisfiable (416),
            unauthorized (401), forbidden (403), rate-limited (429), too-many-jobs (429),
            source-not-kept (409), missing-attributes (422), internal (500).
    """

    id: str
    state: JobState
    progress: float
    method: str
    grid: Grid
    created: datetime.datetime
    timings: JobTimings
    position: int | Unset = UNSET
    name: None | str | Unset = UNSET
    key_name: str | Unset = UNSET
    distance: JobDistance | Unset = UNSET
    owner: str | Unset = UNSET
    request_id: str | Unset = UNSET
    volume_id: str | Unset = UNSET
    attempts: int | Unset = UNSET
    problem: Problem | Unset = UNSET
    additional_properties: dict[str, Any] = _attrs_field(init=False, factory=dict)

    def to_dict(self) -> dict[str, Any]:
        id = self.id

        state = self.state.value

        progress = self.progress

        method = self.method

        grid = self.grid.to_dict()

        created = self.created.isoformat()

        timings = self.timings.to_dict()

        position = self.position

        name: None | str | Unset
        if isinstance(self.name, Unset):
            name = UNSET
        else:
            name = self.name

        key_name = self.key_name

        distance: dict[str, Any] | Unset = UNSET
        if not isinstance(self.distance, Unset):
            distance = self.distance.to_dict()

        owner = self.owner

        request_id = self.request_id

        volume_id = self.volume_id

        attempts = self.attempts

        problem: dict[str, Any] | Unset = UNSET
        if not isinstance(self.problem, Unset):
            problem = self.problem.to_dict()

        field_dict: dict[str, Any] = {}
        field_dict.update(self.additional_properties)
        field_dict.update(
            {
                "id": id,
                "state": state,
                "progress": progress,
                "method": method,
                "grid": grid,
                "created": created,
                "timings": timings,
            }
        )
        if position is not UNSET:
            field_dict["position"] = position
        if name is not UNSET:
            field_dict["name"] = name
        if key_name is not UNSET:
            field_dict["key_name"] = key_name
        if distance is not UNSET:
            field_dict["distance"] = distance
        if owner is not UNSET:
            field_dict["owner"] = owner
        if request_id is not UNSET:
            field_dict["request_id"] = request_id
        if volume_id is not UNSET:
            field_dict["volume_id"] = volume_id
        if attempts is not UNSET:
            field_dict["attempts"] = attempts
        if problem is not UNSET:
            field_dict["problem"] = problem

        return field_dict

    @classmethod
    def from_dict(cls, src_dict: Mapping[str, Any]) -> Self:
        from ..models.grid import Grid
        from ..models.job_distance import JobDistance
        from ..models.job_timings import JobTimings
        from ..models.problem import Problem

        d = dict(src_dict)
        id = d.pop("id")

        state = JobState(d.pop("state"))

        progress = d.pop("progress")

        method = d.pop("method")

        grid = Grid.from_dict(d.pop("grid"))

        created = datetime.datetime.fromisoformat(d.pop("created"))

        timings = JobTimings.from_dict(d.pop("timings"))

        position = d.pop("position", UNSET)

        def _parse_name(data: object) -> None | str | Unset:
            if data is None:
                return data
            if isinstance(data, Unset):
                return data
            return cast(None | str | Unset, data)

        name = _parse_name(d.pop("name", UNSET))

        key_name = d.pop("key_name", UNSET)

        _distance = d.pop("distance", UNSET)
        distance: JobDistance | Unset
        if isinstance(_distance, Unset):
            distance = UNSET
        else:
            distance = JobDistance.from_dict(_distance)

        owner = d.pop("owner", UNSET)

        request_id = d.pop("request_id", UNSET)

        volume_id = d.pop("volume_id", UNSET)

        attempts = d.pop("attempts", UNSET)

        _problem = d.pop("problem", UNSET)
        problem: Problem | Unset
        if isinstance(_problem, Unset):
            problem = UNSET
        else:
            problem = Problem.from_dict(_problem)

        job = cls(
            id=id,
            state=state,
            progress=progress,
            method=method,
            grid=grid,
            created=created,
            timings=timings,
            position=position,
            name=name,
            key_name=key_name,
            distance=distance,
            owner=owner,
            request_id=request_id,
            volume_id=volume_id,
            attempts=attempts,
            problem=problem,
        )

        job.additional_properties = d
        return job

    @property
    def additional_keys(self) -> list[str]:
        return list(self.additional_properties.keys())

    def __getitem__(self, key: str) -> Any:
        return self.additional_properties[key]

    def __setitem__(self, key: str, value: Any) -> None:
        self.additional_properties[key] = value

    def __delitem__(self, key: str) -> None:
        del self.additional_properties[key]

    def __contains__(self, key: str) -> bool:
        return key in self.additional_properties
