"""A thin layer over the generated client (voxd_client.generated, made by generate.sh from
openapi.yaml; never edited by hand): mesh in, numpy array out.

    >>> from voxd_client import Voxd
    >>> vox = Voxd("http://127.0.0.1:8080")
    >>> grid = vox.voxelize("bunny.obj", resolution=128)   # numpy bool array, indexed [x, y, z]

Every call goes through the generated operation modules (their request builders and response
parsers); this layer adds what they leave to the caller:

- uploads carry their media type (model/obj, model/gltf-binary, ...: the generated upload sends
  application/octet-stream, see generator-config.yaml), and a gzip'd mesh (``.gz``) is sent as
  such;
- a job answered with 202 is polled until it ends;
- every problem document (RFC 9457) is raised as a `Problem` exception carrying its ``type``,
  status, title and detail;
- 429 and 503 answers with ``Retry-After`` are retried after the seconds the server asks for
  (at most `max_retries` times, each wait at most `max_retry_wait` seconds).
"""

from __future__ import annotations

import enum
import inspect
import io
import os
import time
import typing
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx

from .generated import AuthenticatedClient, Client
from .generated.api.default import (
    delete_v1_jobs_id,
    get_v1_jobs_id,
    get_v1_volumes_id,
    get_v1_volumes_id_data,
    post_v1_volumes_csg,
    post_v1_voxelize,
)
from .generated.models import CsgExpression, Job, Volume
from .generated.types import UNSET, File, Response

PROBLEM_BASE = "https://voxd.dev/problems/"

# The media type of each mesh format, by file extension (openapi.yaml, POST /v1/voxelize).
MEDIA_TYPES = {
    ".obj": "model/obj",
    ".glb": "model/gltf-binary",
    ".gltf": "model/gltf+json",
    ".stl": "model/stl",
    ".ply": "model/ply",
}

Expr = str | dict | CsgExpression


class Problem(Exception):
    """An RFC 9457 problem document the service answered with (any 4xx or 5xx).

    ``type`` is the full URI (``https://voxd.dev/problems/rate-limited``) and ``kind`` its last
    part (``rate-limited``), the names openapi.yaml lists under Problem.
    """

    def __init__(
        self,
        status: int,
        type: str,
        title: str = "",
        detail: str = "",
        instance: str | None = None,
        request_id: str | None = None,
        retry_after: float | None = None,
    ):
        super().__init__(f"{status} {type}: {detail or title}")
        self.status = status
        self.type = type
        self.title = title
        self.detail = detail
        self.instance = instance
        self.request_id = request_id
        self.retry_after = retry_after

    @property
    def kind(self) -> str:
        return self.type.removeprefix(PROBLEM_BASE)

    @classmethod
    def from_response(cls, response: httpx.Response | Response) -> Problem:
        status = int(response.status_code)
        body: dict[str, Any] = {}
        try:
            parsed = httpx.Response(status, content=response.content).json()
            if isinstance(parsed, dict):
                body = parsed
        except ValueError:
            pass
        return cls(
            status=int(body.get("status", status)),
            type=str(body.get("type", "about:blank")),
            title=str(body.get("title", "")),
            detail=str(body.get("detail", response.content[:200].decode("utf-8", "replace"))),
            instance=body.get("instance"),
            request_id=body.get("request_id"),
            retry_after=_retry_after(response.headers),
        )


class JobFailed(Problem):
    """A job that ended failed (its problem) or canceled."""


def _retry_after(headers: Any) -> float | None:
    value = headers.get("retry-after")
    if value is None:
        return None
    try:
        return max(0.0, float(value))
    except ValueError:
        return None  # an HTTP date: not sent by voxd


class Voxd:
    """The service at `base_url`, with an API key (`token`) where it runs with one.

    `client` is the generated client underneath (voxd_client.generated.Client or
    AuthenticatedClient), for the operations this layer does not wrap.
    """

    def __init__(
        self,
        base_url: str | None = None,
        token: str | None = None,
        *,
        timeout: float = 120.0,
        max_retries: int = 5,
        max_retry_wait: float = 60.0,
        sleep: Callable[[float], None] = time.sleep,
    ):
        base_url = base_url or os.environ.get("VOXD_URL", "http://127.0.0.1:8080")
        token = token if token is not None else os.environ.get("VOXD_API_KEY")
        t = httpx.Timeout(timeout)
        self.client: Client | AuthenticatedClient = (
            AuthenticatedClient(base_url=base_url, token=token, timeout=t)
            if token
            else Client(base_url=base_url, timeout=t)
        )
        self.max_retries = max_retries
        self.max_retry_wait = max_retry_wait
        self.retries = 0  # 429/503 answers retried so far
        self._sleep = sleep

    # ---- the one way requests go out ----

    def call(self, operation: Any, *, headers: dict[str, str] | None = None, **kwargs: Any) -> Response:
        """Runs a generated operation module (e.g. ``get_v1_volumes_id_stats``) with `kwargs`,
        retrying 429 and 503 answers that carry Retry-After; raises `Problem` on any 4xx/5xx.
        `headers` replace the generated request's (a Content-Type, say). Parameters not given
        are not sent (the generated builders would send the document's defaults): the server
        applies its own."""
        for name, p in inspect.signature(operation._get_kwargs).parameters.items():
            if name not in kwargs and p.default is not inspect.Parameter.empty:
                kwargs[name] = UNSET
        request = operation._get_kwargs(**kwargs)
        if headers:
            request.setdefault("headers", {}).update(headers)
        http = self.client.get_httpx_client()
        for attempt in range(self.max_retries + 1):
            response = http.request(**request)
            wait = _retry_after(response.headers)
            if response.status_code in (429, 503) and wait is not None and attempt < self.max_retries:
                self.retries += 1
                self._sleep(min(wait, self.max_retry_wait))
                continue
            break
        if response.status_code >= 400:
            raise Problem.from_response(response)
        return operation._build_response(client=self.client, response=response)

    # ---- voxelization ----

    def submit(
        self,
        mesh: str | os.PathLike | bytes,
        *,
        media_type: str | None = None,
        gzip: bool | None = None,
        **params: Any,
    ) -> Volume | Job:
        """Uploads `mesh` (a path, or the file's bytes with `media_type`) with the query
        parameters of POST /v1/voxelize (``resolution=128``, ``method="surface"``, ``wait=30``,
        ...; enum values as strings). Returns the Volume (201) or the queued Job (202)."""
        if isinstance(mesh, bytes):
            data, name = mesh, ""
        else:
            path = Path(mesh)
            data, name = path.read_bytes(), path.name.lower()
        if gzip is None:
            gzip = name.endswith(".gz") or data[:2] == b"\x1f\x8b"
        stem = name.removesuffix(".gz")
        if media_type is None:
            media_type = MEDIA_TYPES.get(Path(stem).suffix, "application/octet-stream")
        headers = {"Content-Type": media_type}
        if gzip:
            headers["Content-Encoding"] = "gzip"
        response = self.call(
            post_v1_voxelize,
            headers=headers,
            body=File(payload=io.BytesIO(data), file_name=name or None, mime_type=media_type),
            **_enums(post_v1_voxelize, params),
        )
        return response.parsed

    def wait(self, job: Job | str, timeout: float = 600.0, poll: float = 0.25) -> Volume:
        """Polls a job until it ends; the Volume it made, else `JobFailed`."""
        job_id = job if isinstance(job, str) else job.id
        deadline = time.monotonic() + timeout
        while True:
            state: Job = self.call(get_v1_jobs_id, id=job_id).parsed
            if state.state.value == "succeeded":
                return self.volume(state.volume_id)
            if state.state.value in ("failed", "canceled"):
                p = state.problem
                if p:
                    raise JobFailed(p.status, p.type, p.title, p.detail)
                raise JobFailed(409, PROBLEM_BASE + state.state.value, detail=f"job {job_id} {state.state.value}")
            if time.monotonic() > deadline:
                raise TimeoutError(f"job {job_id} still {state.state.value} after {timeout} s")
            self._sleep(poll)
            poll = min(poll * 1.5, 2.0)

    def voxelize_volume(self, mesh: str | os.PathLike | bytes, *, timeout: float = 600.0, **params: Any) -> Volume:
        """`submit`, then `wait` when the job was queued: the stored Volume."""
        params.setdefault("wait", min(timeout, 60.0))
        result = self.submit(mesh, **params)
        return result if isinstance(result, Volume) else self.wait(result, timeout)

    def voxelize(self, mesh: str | os.PathLike | bytes, resolution: int | None = None, **params: Any):
        """Voxelizes `mesh` and returns the volume as a numpy array indexed [x, y, z]: bool for
        bit volumes, uint8 occupancy counts for method="density". Parameters are those of POST
        /v1/voxelize (method, voxel_size, origin, dims, fill, padding, name, ...)."""
        if resolution is not None:
            params["resolution"] = resolution
        volume = self.voxelize_volume(mesh, **params)
        return self.array(volume.id, volume.kind.value)

    # ---- volumes ----

    def volume(self, volume_id: str) -> Volume:
        return self.call(get_v1_volumes_id, id=volume_id).parsed

    def download(self, volume_id: str, format: str = "npy") -> bytes:
        """The volume's file in `format` (vxl, binvox, npy or raw), as bytes."""
        response = self.call(
            get_v1_volumes_id_data, **_enums(get_v1_volumes_id_data, {"id": volume_id, "format": format})
        )
        return response.content

    def array(self, volume_id: str, kind: str | None = None):
        """The volume as a numpy array indexed [x, y, z] (from its .npy download): bool for a bit
        volume, uint8 counts for a density volume. `kind` ("bits" or "density") saves asking."""
        import numpy

        if kind is None:
            kind = self.volume(volume_id).kind.value
        a = numpy.load(io.BytesIO(self.download(volume_id, "npy")), allow_pickle=False)
        return a.astype(bool) if kind == "bits" else a

    def csg(self, expr: Expr, name: str | None = None) -> Volume:
        """Combines stored volumes: `expr` is a volume id, a CsgExpression, or a dict such as
        ``{"op": "difference", "operands": [a, {"op": "union", "operands": [b, c]}]}``."""
        body = CsgExpression.from_dict(expr) if isinstance(expr, dict) else expr
        return self.call(post_v1_volumes_csg, body=body, name=UNSET if name is None else name).parsed

    def cancel(self, job: Job | str) -> Job:
        return self.call(delete_v1_jobs_id, id=job if isinstance(job, str) else job.id).parsed


def _enums(operation: Any, params: dict[str, Any]) -> dict[str, Any]:
    """Turns strings given for enum parameters into the generated enum classes (by the
    annotations of the operation's request builder); `format` is the generated `format_`."""
    hints = typing.get_type_hints(operation._get_kwargs)
    out: dict[str, Any] = {}
    for key, value in params.items():
        name = "format_" if key == "format" else key
        if name not in hints:
            raise TypeError(f"{operation.__name__.rsplit('.', 1)[-1]} takes no parameter {key!r}")
        if not isinstance(value, (str, int)) or isinstance(value, bool):
            out[name] = value
            continue
        for cls in typing.get_args(hints[name]):
            if inspect.isclass(cls) and issubclass(cls, enum.Enum) and not isinstance(value, cls):
                value = cls(value)
                break
        out[name] = value
    return out
