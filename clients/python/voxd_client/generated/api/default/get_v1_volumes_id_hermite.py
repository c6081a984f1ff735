from http import HTTPStatus
from io import BytesIO
from typing import Any, cast
from urllib.parse import quote

import httpx

from ... import errors
from ...client import AuthenticatedClient, Client
from ...models.problem import Problem
from ...types import UNSET, File, Response, Unset


def _get_kwargs(
    id: str,
    *,
    if_none_match: str | Unset = UNSET,
    if_match: str | Unset = UNSET,
) -> dict[str, Any]:
    headers: dict[str, Any] = {}
    if not isinstance(if_none_match, Unset):
        headers["If-None-Match"] = if_none_match

    if not isinstance(if_match, Unset):
        headers["If-Match"] = if_match

    _kwargs: dict[str, Any] = {
        "method": "get",
        "url": "/v1/volumes/{id}/hermite".format(
            id=quote(str(id), safe=""),
        ),
    }

    _kwargs["headers"] = headers
    return _kwargs


def _parse_response(
    *, client: AuthenticatedClient | Client, response: httpx.Response
) -> Any | File | Problem | None:
    if response.status_code == 200:
        response_200 = File(payload=BytesIO(response.content))

        return response_200

    if response.status_code == 304:
        response_304 = cast(Any, None)
        return response_304

    if response.status_code == 401:
        response_401 = Problem.from_dict(response.json())

        return response_401

    if response.status_code == 404:
        response_404 = Problem.from_dict(response.json())

        return response_404

    if response.status_code == 409:
        response_409 = Problem.from_dict(response.json())

        return response_409

    if response.status_code == 412:
        response_412 = Problem.from_dict(response.json())

        return response_412

    if response.status_code == 422:
        response_422 = Problem.from_dict(response.json())

        return response_422

    if response.status_code == 429:
        response_429 = Problem.from_dict(response.json())

        return response_429

    if response.status_code == 503:
        response_503 = Problem.from_dict(response.json())

        return response_503

    if client.raise_on_unexpected_status:
        raise errors.UnexpectedStatus(response.status_code, response.content)
    else:
        return None


def _build_response(
    *, client: AuthenticatedClient | Client, response: httpx.Response
) -> Response[Any | File | Problem]:
    return Response(
        status_code=HTTPStatus(response.status_code),
        content=response.content,
        headers=response.headers,
        parsed=_parse_response(client=client, response=response),
    )


def sync_detailed(
    id: str,
    *,
    client: AuthenticatedClient | Client,
    if_none_match: str | Unset = UNSET,
    if_match: str | Unset = UNSET,
) -> Response[Any | File | Problem]:
    """The Hermite data of the volume's mesh (.npz)

     Of the solid of the mesh the volume was made from (kept in the store: source.kept) on the volume's
    grid with the fill it used: every edge between neighbouring voxel centres whose ends differ, where
    the mesh crosses it (exact, with the solid's tie rules) and the crossed triangle's unit normal;
    arrays edges (N,4) uint32, t (N,) float64, points (N,3) float64 (world units), normals (N,3)
    float64, crossed and lower_inside (N,) bool, origin, voxel_size, dims (docs/format.md, Hermite
    data). A volume that keeps no mesh is source-not-kept (409); more differing edges than --max-
    triangles is too-many-triangles (422); the memory is admitted before the work.

    Args:
        id (str):
        if_none_match (str | Unset):
        if_match (str | Unset):

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Response[Any | File | Problem]
    """

    kwargs = _get_kwargs(
        id=id,
        if_none_match=if_none_match,
        if_match=if_match,
    )

    response = client.get_httpx_client().request(
        **kwargs,
    )

    return _build_response(client=client, response=response)


def sync(
    id: str,
    *,
    client: AuthenticatedClient | Client,
    if_none_match: str | Unset = UNSET,
    if_match: str | Unset = UNSET,
) -> Any | File | Problem | None:
    """The Hermite data of the volume's mesh (.npz)

     Of the solid of the mesh the volume was made from (kept in the store: source.kept) on the volume's
    grid with the fill it used: every edge between neighbouring voxel centres whose ends differ, where
    the mesh crosses it (exact, with the solid's tie rules) and the crossed triangle's unit normal;
    arrays edges (N,4) uint32, t (N,) float64, points (N,3) float64 (world units), normals (N,3)
    float64, crossed and lower_inside (N,) bool, origin, voxel_size, dims (docs/format.md, Hermite
    data). A volume that keeps no mesh is source-not-kept (409); more differing edges than --max-
    triangles is too-many-triangles (422); the memory is admitted before the work.

    Args:
        id (str):
        if_none_match (str | Unset):
        if_match (str | Unset):

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Any | File | Problem
    """

    return sync_detailed(
        id=id,
        client=client,
        if_none_match=if_none_match,
        if_match=if_match,
    ).parsed


async def asyncio_detailed(
    id: str,
    *,
    client: AuthenticatedClient | Client,
    if_none_match: str | Unset = UNSET,
    if_match: str | Unset = UNSET,
) -> Response[Any | File | Problem]:
    """The Hermite data of the volume's mesh (.npz)

     Of the solid of the mesh the volume was made from (kept in the store: source.kept) on the volume's
    grid with the fill it used: every edge between neighbouring voxel centres whose ends differ, where
    the mesh crosses it (exact, with the solid's tie rules) and the crossed triangle's unit normal;
    arrays edges (N,4) uint32, t (N,) float64, points (N,3) float64 (world units), normals (N,3)
    float64, crossed and lower_inside (N,) bool, origin, voxel_size, dims (docs/format.md, Hermite
    data). A volume that keeps no mesh is source-not-kept (409); more differing edges than --max-
    triangles is too-many-triangles (422); the memory is admitted before the work.

    Args:
        id (str):
        if_none_match (str | Unset):
        if_match (str | Unset):

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Response[Any | File | Problem]
    """

    kwargs = _get_kwargs(
        id=id,
        if_none_match=if_none_match,
        if_match=if_match,
    )

    response = await client.get_async_httpx_client().request(**kwargs)

    return _build_response(client=client, response=response)


async def asyncio(
    id: str,
    *,
    client: AuthenticatedClient | Client,
    if_none_match: str | Unset = UNSET,
    if_match: str | Unset = UNSET,
) -> Any | File | Problem | None:
    """The Hermite data of the volume's mesh (.npz)

     Of the solid of the mesh the volume was made from (kept in the store: source.kept) on the volume's
    grid with the fill it used: every edge between neighbouring voxel centres whose ends differ, where
    the mesh crosses it (exact, with the solid's tie rules) and the crossed triangle's unit normal;
    arrays edges (N,4) uint32, t (N,) float64, points (N,3) float64 (world units), normals (N,3)
    float64, crossed and lower_inside (N,) bool, origin, voxel_size, dims (docs/format.md, Hermite
    data). A volume that keeps no mesh is source-not-kept (409); more differing edges than --max-
    triangles is too-many-triangles (422); the memory is admitted before the work.

    Args:
        id (str):
        if_none_match (str | Unset):
        if_match (str | Unset):

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Any | File | Problem
    """

    return (
        await asyncio_detailed(
            id=id,
            client=client,
            if_none_match=if_none_match,
            if_match=if_match,
        )
    ).parsed
