"""voxd's Python client.

`Voxd` (voxd_client.convenience, hand-written) is the short way: ``Voxd(url).voxelize(path,
resolution=128)`` returns a numpy array. Every operation of openapi.yaml is also in
``voxd_client.generated`` (made by clients/python/generate.sh with openapi-python-client; do
not edit it), one module per operation under ``voxd_client.generated.api.default``.
"""

from .convenience import MEDIA_TYPES, JobFailed, Problem, Voxd
from .generated import AuthenticatedClient, Client


def voxelize(mesh, resolution=None, *, base_url=None, token=None, **params):
    """`Voxd(base_url, token).voxelize(mesh, resolution, **params)`: the volume as a numpy
    array (base_url defaults to $VOXD_URL, else http://127.0.0.1:8080; token to $VOXD_API_KEY)."""
    return Voxd(base_url, token).voxelize(mesh, resolution, **params)


__all__ = ["MEDIA_TYPES", "AuthenticatedClient", "Client", "JobFailed", "Problem", "Voxd", "voxelize"]
