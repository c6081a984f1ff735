"""The Python client against a running voxd (scripts/client-check.sh starts it on 127.0.0.1 with
an API keys file and sets VOXD_URL, VOXD_KEY, VOXD_SLOW_KEY, VOXD_MESHES).

Every operation of openapi.yaml is called here, through the generated modules
(voxd_client.generated.api.default) or the convenience layer built on them; test_every_operation_
is_covered checks that against the document and the generated package.
"""

import gzip
import io
import os
import re
import time
from pathlib import Path

import httpx
import numpy as np
import pytest

from voxd_client import Problem, Voxd, voxelize
from voxd_client.generated import AuthenticatedClient, Client
from voxd_client.generated.api import default as api
from voxd_client.generated.api.default import (
    delete_v1_jobs_id,
    delete_v1_volumes_id,
    get_healthz,
    get_metrics,
    get_openapi_yaml,
    get_readyz,
    get_v1_jobs_id,
    get_v1_viewer_file,
    get_v1_volumes,
    get_v1_volumes_id,
    get_v1_volumes_id_data,
    get_v1_volumes_id_hermite,
    get_v1_volumes_id_mesh,
    get_v1_volumes_id_normals,
    get_v1_volumes_id_preview_png,
    get_v1_volumes_id_stats,
    get_v1_volumes_id_view,
    post_v1_volumes_csg,
    post_v1_volumes_id_morphology,
    post_v1_volumes_id_query,
    post_v1_volumes_id_sdf,
    post_v1_volumes_id_threshold,
    post_v1_volumes_intersect,
    post_v1_voxelize,
)
from voxd_client.generated.models import (
    CsgExpression,
    CsgExpressionOp,
    GetV1ViewerFileFile,
    GetV1VolumesIdDataFormat,
    GetV1VolumesIdMeshAlgorithm,
    GetV1VolumesIdMeshFormat,
    GetV1VolumesIdPreviewPngAxis,
    Job,
    PostV1VolumesIdMorphologyBody,
    PostV1VolumesIdMorphologyBodyOp,
    PostV1VolumesIdQueryBodyType0,
    PostV1VolumesIntersectBody,
    PostV1VoxelizeFormat,
    Volume,
)
from voxd_client.generated.models import (
    Problem as ProblemModel,
)
from voxd_client.generated.types import File

URL = os.environ["VOXD_URL"]
KEY = os.environ["VOXD_KEY"]
SLOW_KEY = os.environ["VOXD_SLOW_KEY"]
MESHES = Path(os.environ["VOXD_MESHES"])
CALLED = set()  # the generated operation modules the tests ran

# A unit tetrahedron, in the two text formats the repository has no file of.
STL = b"""solid t
facet normal 0 0 -1
outer loop
vertex 0 0 0
vertex 0 1 0
vertex 1 0 0
endloop
endfacet
facet normal 0 -1 0
outer loop
vertex 0 0 0
vertex 1 0 0
vertex 0 0 1
endloop
endfacet
facet normal -1 0 0
outer loop
vertex 0 0 0
vertex 0 0 1
vertex 0 1 0
endloop
endfacet
facet normal 1 1 1
outer loop
vertex 1 0 0
vertex 0 1 0
vertex 0 0 1
endloop
endfacet
endsolid t
"""
PLY = b"""ply
format ascii 1.0
element vertex 4
property float x
property float y
property float z
element face 4
property list uchar int vertex_indices
end_header
0 0 0
1 0 0
0 1 0
0 0 1
3 0 2 1
3 0 1 3
3 0 3 2
3 1 2 3
"""
OBJ = (MESHES / "spot.obj").read_bytes()
GRID = {"origin": "-1,-1,-1", "voxel_size": 0.25, "dims": "8,8,8"}


def ran(module):
    CALLED.add(module.__name__.rsplit(".", 1)[-1])
    return module


@pytest.fixture(scope="module")
def vox():
    v = Voxd(URL, KEY)
    yield v
    v.client.get_httpx_client().close()


@pytest.fixture(scope="module")
def client():
    with AuthenticatedClient(base_url=URL, token=KEY, raise_on_unexpected_status=True) as c:
        yield c


@pytest.fixture(scope="module")
def box(vox):
    """Two aligned bit volumes of the glTF box (an explicit grid)."""
    a = vox.voxelize_volume(MESHES / "Box.gltf", **GRID, name="box a")
    b = vox.voxelize_volume(MESHES / "Box.gltf", origin="-0.75,-1,-1", dims="8,8,8", voxel_size=0.25, name="box b")
    return a, b


# ---- the service's own routes ----


def test_health_ready_metrics_and_the_document(client):
    assert ran(get_healthz).sync(client=client).status == "ok"
    ready = ran(get_readyz).sync(client=client)
    assert ready.status == "ready" and ready.engine
    assert "voxd_queue_depth" in ran(get_metrics).sync(client=client)
    doc = ran(get_openapi_yaml).sync(client=client)
    assert doc.startswith("openapi: 3.")
    assert doc == (MESHES.parent.parent / "openapi.yaml").read_text()


# ---- uploads: every mesh format with its media type, through the generated module ----


@pytest.mark.parametrize(
    "mesh, media_type, fmt",
    [
        ("spot.obj", "model/obj", "obj"),
        ("Box.gltf", "model/gltf+json", "gltf"),
        ("Fox.glb", "model/gltf-binary", "glb"),
        (STL, "model/stl", "stl"),
        (PLY, "model/ply", "ply"),
    ],
)
def test_upload_with_its_media_type(vox, mesh, media_type, fmt):
    data = mesh if isinstance(mesh, bytes) else (MESHES / mesh).read_bytes()
    # The generated upload sends application/octet-stream: `format` names the mesh.
    r = ran(post_v1_voxelize).sync_detailed(
        client=vox.client,
        body=File(payload=io.BytesIO(data)),
        format_=PostV1VoxelizeFormat(fmt),
        resolution=16,
        wait=60,
    )
    assert r.status_code == 201, r.content
    assert isinstance(r.parsed, Volume) and r.parsed.source.format_ == fmt
    # The convenience layer sends the model/* type itself (no `format`), gzip'd or not, and no
    # parameter that was not asked for (the server's defaults apply).
    v = vox.submit(data, media_type=media_type, resolution=16, wait=60)
    same = (r.parsed.source.sha256, r.parsed.grid.dims, r.parsed.solid_voxels)
    assert v.source.format_ == fmt and (v.source.sha256, v.grid.dims, v.solid_voxels) == same
    z = vox.submit(gzip.compress(data), media_type=media_type, resolution=16, wait=60)
    assert z.source.format_ == fmt and (z.grid.dims, z.solid_voxels) == same[1:]  # (the sha256 is the body's)


def test_voxelize_returns_a_numpy_array(vox, tmp_path):
    grid = vox.voxelize(MESHES / "spot.obj", resolution=24)
    assert isinstance(grid, np.ndarray) and grid.dtype == np.bool_
    assert max(grid.shape) == 24 and 0 < grid.sum() < grid.size
    # The module function, the grid given explicitly, a density volume, a .gz path.
    path = tmp_path / "spot.obj.gz"
    path.write_bytes(gzip.compress(OBJ))
    again = voxelize(path, 24, base_url=URL, token=KEY)
    assert (again == grid).all()
    explicit = vox.voxelize(MESHES / "Box.gltf", **GRID, method="surface")
    assert explicit.shape == (8, 8, 8) and explicit.any()
    density = vox.voxelize(MESHES / "spot.obj", resolution=12, method="density", density_factor=2)
    assert density.dtype == np.uint8 and density.max() <= 8


def test_the_readme_session(monkeypatch):
    """The Python session of clients/python/README.md (and README.md), as written, from the
    repository's root, the server's address put in and its key from $VOXD_API_KEY."""
    readme = (Path(__file__).parent.parent / "README.md").read_text()
    block = re.search(r"```python\n(.*?)```", readme, re.DOTALL).group(1)
    assert len(block.strip().splitlines()) == 3
    monkeypatch.chdir(MESHES.parent.parent)
    monkeypatch.setenv("VOXD_API_KEY", KEY)
    session = {}
    exec(block.replace("http://127.0.0.1:8080", URL), session)  # noqa: S102 (the README's own code)
    grid = session["grid"]
    assert grid.dtype == np.bool_ and max(grid.shape) == 128 and grid.any()


def test_a_queued_job_is_polled_and_can_be_canceled(vox, client):
    job = vox.submit(OBJ, media_type="model/obj", resolution=20, wait=0)
    assert isinstance(job, Job)
    state = ran(get_v1_jobs_id).sync(job.id, client=client)
    assert state.id == job.id and state.state.value in ("queued", "running", "succeeded")
    volume = vox.wait(job)
    assert volume.grid.dims and max(volume.grid.dims) == 20
    # Cancel: a big job first (one worker), so that the next one waits in the queue.
    big = vox.submit(OBJ, media_type="model/obj", resolution=128, fill="winding", wait=0)
    queued = vox.submit(OBJ, media_type="model/obj", resolution=21, wait=0)
    r = ran(delete_v1_jobs_id).sync_detailed(queued.id, client=client)
    if r.status_code == 200:
        assert r.parsed.state.value == "canceled"
    else:  # it had already run: not-cancelable, typed
        assert r.status_code == 409 and r.parsed.type_.endswith("/not-cancelable")
    try:
        vox.cancel(big)
    except Problem as p:
        assert p.kind == "not-cancelable"
    # A finished job is not cancelable: the generated parser's Problem, and the layer's exception.
    with pytest.raises(Problem) as e:
        vox.cancel(job)
    assert (e.value.status, e.value.kind) == (409, "not-cancelable")


# ---- volumes ----


def test_volume_operations(vox, client, box):
    a, b = box
    assert ran(get_v1_volumes_id).sync(a.id, client=client).name == "box a"
    page = ran(get_v1_volumes).sync(client=client, limit=1000)
    assert {a.id, b.id} <= {v.id for v in page.volumes}
    stats = ran(get_v1_volumes_id_stats).sync(a.id, client=client)
    assert stats.solid_voxels == a.solid_voxels > 0
    q = ran(post_v1_volumes_id_query).sync(
        a.id, client=client, body=PostV1VolumesIdQueryBodyType0(points=[[0.0, 0.0, 0.0], [5.0, 5.0, 5.0]])
    )
    assert [p.inside for p in q.points] == [True, False]
    n = ran(get_v1_volumes_id_normals).sync(a.id, client=client, points="0.49,0,0;0,0,0")
    assert len(n.normals) == 2
    png = ran(get_v1_volumes_id_preview_png).sync(a.id, client=client, axis=GetV1VolumesIdPreviewPngAxis.X, slice_=3)
    assert png.payload.read(8) == b"\x89PNG\r\n\x1a\n"
    proj = ran(get_v1_volumes_id_preview_png).sync(a.id, client=client)
    assert proj.payload.read(4) == b"\x89PNG"
    glb = ran(get_v1_volumes_id_mesh).sync(
        a.id, client=client, algorithm=GetV1VolumesIdMeshAlgorithm.CUBES, format_=GetV1VolumesIdMeshFormat.GLB
    )
    assert glb.payload.read(4) == b"glTF"
    npz = ran(get_v1_volumes_id_hermite).sync(a.id, client=client)
    assert npz.payload.read(2) == b"PK"  # the .npz of the kept mesh's Hermite data
    page = ran(get_v1_volumes_id_view).sync(a.id, client=client)
    assert isinstance(page, str) and "/v1/viewer/three.module.min.js" in page
    licence = ran(get_v1_viewer_file).sync(GetV1ViewerFileFile.LICENSE_THREE_TXT, client=client)
    assert isinstance(licence, str) and "MIT License" in licence
    raw = ran(get_v1_volumes_id_data).sync(a.id, client=client, format_=GetV1VolumesIdDataFormat.RAW)
    assert len(raw.payload.read()) == 8 * 8 * 8
    for fmt in ("vxl", "binvox", "npy", "raw"):
        assert len(vox.download(a.id, format=fmt)) > 0
    arr = vox.array(a.id)
    assert arr.shape == (8, 8, 8) and int(arr.sum()) == a.solid_voxels
    overlap = ran(post_v1_volumes_intersect).sync(client=client, body=PostV1VolumesIntersectBody(a=a.id, b=b.id))
    assert overlap.voxels == a.solid_voxels == b.solid_voxels  # the same box on two grids
    m = ran(post_v1_volumes_id_morphology).sync(
        a.id, client=client, body=PostV1VolumesIdMorphologyBody(op=PostV1VolumesIdMorphologyBodyOp.ERODE, radius=1)
    )
    assert isinstance(m, Volume) and m.solid_voxels < a.solid_voxels
    r = ran(delete_v1_volumes_id).sync_detailed(m.id, client=client)
    assert r.status_code == 204
    with pytest.raises(Problem) as e:
        vox.volume(m.id)
    assert (e.value.status, e.value.kind) == (404, "not-found")


def test_csg(vox, client, box):
    a, b = box
    # Nested, through the layer (a dict) and through the generated model.
    union = vox.csg({"op": "union", "operands": [a.id, {"op": "intersection", "operands": [a.id, b.id]}]}, name="u")
    assert union.solid_voxels == a.solid_voxels and union.name == "u"
    assert union.grid.dims == [8, 8, 8]  # a's grid holds the intersection's
    assert vox.csg({"op": "union", "operands": [a.id, b.id]}).grid.dims == [9, 8, 8]
    core = ran(post_v1_volumes_id_morphology).sync(
        a.id, client=client, body=PostV1VolumesIdMorphologyBody(op=PostV1VolumesIdMorphologyBodyOp.ERODE, radius=1)
    )
    expr = CsgExpression(
        op=CsgExpressionOp.DIFFERENCE, operands=[a.id, CsgExpression(op=CsgExpressionOp.UNION, operands=[core.id])]
    )
    shell = ran(post_v1_volumes_csg).sync(client=client, body=expr)
    assert shell.solid_voxels == a.solid_voxels - core.solid_voxels > 0
    expected = vox.array(a.id) & ~vox.array(core.id)
    assert (vox.array(shell.id) == expected).all()
    # A bare volume id is an expression too.
    copy = ran(post_v1_volumes_csg).sync(client=client, body=a.id)
    assert copy.solid_voxels == a.solid_voxels


def test_distance_volumes(vox, client, box):
    a, _ = box
    # The bit volume's signed distance transform, and back: threshold at 0 is the volume again.
    sdf = ran(post_v1_volumes_id_sdf).sync(a.id, client=client, band=2, name="box sdf")
    assert isinstance(sdf, Volume) and sdf.kind == "sparse-distance"
    back = ran(post_v1_volumes_id_threshold).sync(sdf.id, client=client, level=0.0)
    assert isinstance(back, Volume) and back.kind == "bits"
    assert (vox.array(back.id) == vox.array(a.id)).all()
    # Offsets grow outwards with the level; a bit volume is not a distance volume.
    grown = ran(post_v1_volumes_id_threshold).sync(sdf.id, client=client, level=0.3)
    assert grown.solid_voxels > a.solid_voxels
    refused = post_v1_volumes_id_threshold.sync(a.id, client=client, level=0.0)
    assert isinstance(refused, ProblemModel) and refused.status == 422 and refused.type_.endswith("wrong-volume-kind")
    d = vox.download(sdf.id, format="npy")
    assert len(d) > 0


# ---- problems come back typed ----


def test_problems_are_typed(vox, client):
    cases = [
        (lambda: vox.volume("nope"), 404, "not-found"),
        (lambda: vox.submit(b"not a mesh at all", media_type="model/obj", resolution=8), 422, "invalid-mesh"),
        (lambda: vox.submit(OBJ, media_type="model/obj", resolution=8, voxel_size=0.5), 400, "invalid-parameter"),
        (lambda: vox.submit(OBJ, media_type="model/obj", resolution=4_000_000), 422, "grid-too-large"),
        (lambda: vox.csg({"op": "union", "operands": ["nope"]}), 404, "not-found"),
        (lambda: Voxd(URL, "not-a-key").volume("x"), 401, "unauthorized"),
    ]
    for call, status, kind in cases:
        with pytest.raises(Problem) as e:
            call()
        p = e.value
        assert (p.status, p.kind) == (status, kind), p
        assert p.type == f"https://voxd.dev/problems/{kind}" and p.title and p.detail
    # The generated parsers return the Problem model for documented statuses.
    r = get_v1_volumes_id.sync_detailed("nope", client=client)
    assert r.status_code == 404 and isinstance(r.parsed, ProblemModel) and r.parsed.type_.endswith("/not-found")
    anonymous = Client(base_url=URL)
    r = get_v1_volumes.sync_detailed(client=anonymous)
    assert r.status_code == 401 and r.parsed.type_.endswith("/unauthorized")
    assert "Bearer" in r.headers["www-authenticate"]


# ---- 429 is retried after Retry-After ----


def test_rate_limited_requests_are_retried_after_retry_after():
    slept = []
    slow = Voxd(URL, SLOW_KEY, sleep=lambda s: (slept.append(s), time.sleep(s)))
    for _ in range(3):  # the key may make one request a second, bursts of one
        assert slow.call(get_v1_volumes, limit=1).status_code == 200
    assert slow.retries >= 2 and all(s >= 1 for s in slept), slept
    # Without retries the 429 is a typed problem carrying Retry-After.
    strict = Voxd(URL, SLOW_KEY, max_retries=0)
    with pytest.raises(Problem) as e:
        for _ in range(3):
            strict.call(get_v1_volumes, limit=1)
    assert (e.value.status, e.value.kind) == (429, "rate-limited") and e.value.retry_after >= 1
    metrics = get_metrics.sync(client=Client(base_url=URL))
    limited = re.search(r'voxd_key_rate_limited_total\{key="slow"\} (\d+)', metrics)
    assert limited and int(limited.group(1)) >= 3


def test_busy_is_retried_a_bounded_number_of_times():
    """503 with Retry-After (busy, storage-unavailable) is retried like 429; after max_retries
    the problem is raised. (A transport that answers as a busy server would: no server can be
    made busy on demand.)"""
    answers = []

    def handler(request):
        answers.append(request.url.path)
        if len(answers) <= 2:
            problem = {"type": "https://voxd.dev/problems/busy", "title": "Busy", "status": 503, "detail": "later"}
            return httpx.Response(503, json=problem, headers={"Retry-After": "7"})
        return httpx.Response(200, json={"status": "ok"})

    slept = []
    v = Voxd("http://voxd.test", sleep=slept.append, max_retries=2, max_retry_wait=5)
    v.client.set_httpx_client(httpx.Client(base_url="http://voxd.test", transport=httpx.MockTransport(handler)))
    assert v.call(get_healthz).parsed.status == "ok"
    assert (len(answers), slept, v.retries) == (3, [5, 5], 2)  # each wait capped at max_retry_wait
    answers.clear()
    v.max_retries = 1
    with pytest.raises(Problem) as e:
        v.call(get_healthz)
    assert (e.value.status, e.value.kind, e.value.retry_after, len(answers)) == (503, "busy", 7, 2)


def test_the_layer_sends_only_what_was_asked():
    """The generated builder sends every parameter the document gives a default; the layer sends
    only those given, so that the server's defaults apply (and its cross-parameter rules see
    what the caller meant)."""
    seen = []

    def handler(request):
        seen.append((dict(request.url.params), request.headers["content-type"]))
        return httpx.Response(400, json={"type": "https://voxd.dev/problems/invalid-parameter", "status": 400})

    generated = post_v1_voxelize._get_kwargs(body=File(payload=io.BytesIO(b"")))
    assert {"method", "padding", "wait"} <= generated["params"].keys()
    # fill has no default in the document (auto is the server's): a generated upload that sent
    # one would be refused with method=surface.
    assert "fill" not in generated["params"]
    v = Voxd("http://voxd.test")
    v.client.set_httpx_client(httpx.Client(base_url="http://voxd.test", transport=httpx.MockTransport(handler)))
    with pytest.raises(Problem):
        v.submit(b"v 0 0 0", media_type="model/obj", resolution=8)
    assert seen == [({"resolution": "8"}, "model/obj")]


# ---- coverage: last, so that it sees what the others ran ----


def test_every_operation_is_covered():
    doc = (MESHES.parent.parent / "openapi.yaml").read_text()
    operations = set()
    path = None
    for line in doc.splitlines():
        if line == "components:":
            break
        if m := re.fullmatch(r"  (/\S*):", line):
            path = m.group(1)
        elif (m := re.fullmatch(r"    (get|post|delete|put|patch):", line)) and path:
            operations.add(m.group(1) + "_" + re.sub(r"[^a-z0-9]+", "_", path.lower()).strip("_"))
    generated = {p.stem for p in Path(api.__file__).parent.glob("*.py") if p.stem != "__init__"}
    assert operations == generated, "the generated client lacks (or adds) operations"
    assert operations - CALLED == set(), "operations no test called"
