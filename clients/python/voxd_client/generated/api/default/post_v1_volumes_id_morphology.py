from http import HTTPStatus
from typing import Any
from urllib.parse import quote

import httpx

from ... import errors
from ...client import AuthenticatedClient, Client
from ...models.post_v1_volumes_id_morphology_body import PostV1VolumesIdMorphologyBody
from ...models.problem import Problem
from ...models.volume import Volume
from ...types import UNSET, Response, Unset


def _get_kwargs(
    id: str,
    *,
    body: PostV1VolumesIdMorphologyBody,
    name: str | Unset = UNSET,
) -> dict[str, Any]:
    headers: dict[str, Any] = {}

    params: dict[str, Any] = {}

    params["name"] = name

    params = {k: v for k, v in params.items() if v is not UNSET and v is not None}

    _kwargs: dict[str, Any] = {
        "method": "post",
        "url": "/v1/volumes/{id}/morphology".format(
            id=quote(str(id), safe=""),
        ),
        "params": params,
    }

    _kwargs["json"] = body.to_dict()

    headers["Content-Type"] = "application/json"

    _kwargs["headers"] = headers
    return _kwargs


def _parse_response(
    *, client: AuthenticatedClient | Client, response: httpx.Response
) -> Problem | Volume | None:
    if response.status_code == 201:
        response_201 = Volume.from_dict(response.json())

        return response_201

    if response.status_code == 400:
        response_400 = Problem.from_dict(response.json())

        return response_400

    if response.status_code == 401:
        response_401 = Problem.from_dict(response.json())

        return response_401

    if response.status_code == 403:
        response_403 = Problem.from_dict(response.json())

        return response_403

    if response.status_code == 404:
        response_404 = Problem.from_dict(response.json())

        return response_404

    if response.status_code == 422:
        response_422 = Problem.from_dict(response.json())

        return response_422

    if response.status_code == 429:
        response_429 = Problem.from_dict(response.json())

        return response_429

    if response.status_code == 507:
        response_507 = Problem.from_dict(response.json())

        return response_507

    if client.raise_on_unexpected_status:
        raise errors.UnexpectedStatus(response.status_code, response.content)
    else:
        return None


def _build_response(
    *, client: AuthenticatedClient | Client, response: httpx.Response
) -> Response[Problem | Volume]:
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
    body: PostV1VolumesIdMorphologyBody,
    name: str | Unset = UNSET,
) -> Response[Problem | Volume]:
    """Dilate, erode, open or close a stored bit volume into a new volume

     Kernels: cube (Chebyshev ball), cross (Manhattan ball: r steps of the 6-neighbourhood),
    sphere (Euclidean ball). Voxels outside the grid are empty. With grow, dilate and close
    work on (and return) the grid enlarged by radius voxels on every side. A volume with
    channels keeps them: a voxel set in the source keeps its values, an added one takes
    those of the nearest set source voxel (Euclidean, centre to centre).

    Args:
        id (str):
        name (str | Unset): at most 256 characters, none of them control characters
        body (PostV1VolumesIdMorphologyBody):

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Response[Problem | Volume]
    """

    kwargs = _get_kwargs(
        id=id,
        body=body,
        name=name,
    )

    response = client.get_httpx_client().request(
        **kwargs,
    )

    return _build_response(client=client, response=response)


def sync(
    id: str,
    *,
    client: AuthenticatedClient | Client,
    body: PostV1VolumesIdMorphologyBody,
    name: str | Unset = UNSET,
) -> Problem | Volume | None:
    """Dilate, erode, open or close a stored bit volume into a new volume

     Kernels: cube (Chebyshev ball), cross (Manhattan ball: r steps of the 6-neighbourhood),
    sphere (Euclidean ball). Voxels outside the grid are empty. With grow, dilate and close
    work on (and return) the grid enlarged by radius voxels on every side. A volume with
    channels keeps them: a voxel set in the source keeps its values, an added one takes
    those of the nearest set source voxel (Euclidean, centre to centre).

    Args:
        id (str):
        name (str | Unset): at most 256 characters, none of them control characters
        body (PostV1VolumesIdMorphologyBody):

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Problem | Volume
    """

    return sync_detailed(
        id=id,
        client=client,
        body=body,
        name=name,
    ).parsed


async def asyncio_detailed(
    id: str,
    *,
    client: AuthenticatedClient | Client,
    body: PostV1VolumesIdMorphologyBody,
    name: str | Unset = UNSET,
) -> Response[Problem | Volume]:
    """Dilate, erode, open or close a stored bit volume into a new volume

     Kernels: cube (Chebyshev ball), cross (Manhattan ball: r steps of the 6-neighbourhood),
    sphere (Euclidean ball). Voxels outside the grid are empty. With grow, dilate and close
    work on (and return) the grid enlarged by radius voxels on every side. A volume with
    channels keeps them: a voxel set in the source keeps its values, an added one takes
    those of the nearest set source voxel (Euclidean, centre to centre).

    Args:
        id (str):
        name (str | Unset): at most 256 characters, none of them control characters
        body (PostV1VolumesIdMorphologyBody):

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Response[Problem | Volume]
    """

    kwargs = _get_kwargs(
        id=id,
        body=body,
        name=name,
    )

    response = await client.get_async_httpx_client().request(**kwargs)

    return _build_response(client=client, response=response)


async def asyncio(
    id: str,
    *,
    client: AuthenticatedClient | Client,
    body: PostV1VolumesIdMorphologyBody,
    name: str | Unset = UNSET,
) -> Problem | Volume | None:
    """Dilate, erode, open or close a stored bit volume into a new volume

     Kernels: cube (Chebyshev ball), cross (Manhattan ball: r steps of the 6-neighbourhood),
    sphere (Euclidean ball). Voxels outside the grid are empty. With grow, dilate and close
    work on (and return) the grid enlarged by radius voxels on every side. A volume with
    channels keeps them: a voxel set in the source keeps its values, an added one takes
    those of the nearest set source voxel (Euclidean, centre to centre).

    Args:
        id (str):
        name (str | Unset): at most 256 characters, none of them control characters
        body (PostV1VolumesIdMorphologyBody):

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Problem | Volume
    """

    return (
        await asyncio_detailed(
            id=id,
            client=client,
            body=body,
            name=name,
        )
    ).parsed
