from http import HTTPStatus
from typing import Any
from urllib.parse import quote

import httpx

from ... import errors
from ...client import AuthenticatedClient, Client
from ...models.post_v1_volumes_id_query_body_type_0 import PostV1VolumesIdQueryBodyType0
from ...models.post_v1_volumes_id_query_body_type_1 import PostV1VolumesIdQueryBodyType1
from ...models.post_v1_volumes_id_query_response_200 import (
    PostV1VolumesIdQueryResponse200,
)
from ...models.problem import Problem
from ...types import Response


def _get_kwargs(
    id: str,
    *,
    body: PostV1VolumesIdQueryBodyType0 | PostV1VolumesIdQueryBodyType1,
) -> dict[str, Any]:
    headers: dict[str, Any] = {}

    _kwargs: dict[str, Any] = {
        "method": "post",
        "url": "/v1/volumes/{id}/query".format(
            id=quote(str(id), safe=""),
        ),
    }

    if isinstance(body, PostV1VolumesIdQueryBodyType0):
        _kwargs["json"] = body.to_dict()
    else:
        _kwargs["json"] = body.to_dict()

    headers["Content-Type"] = "application/json"

    _kwargs["headers"] = headers
    return _kwargs


def _parse_response(
    *, client: AuthenticatedClient | Client, response: httpx.Response
) -> PostV1VolumesIdQueryResponse200 | Problem | None:
    if response.status_code == 200:
        response_200 = PostV1VolumesIdQueryResponse200.from_dict(response.json())

        return response_200

    if response.status_code == 400:
        response_400 = Problem.from_dict(response.json())

        return response_400

    if response.status_code == 401:
        response_401 = Problem.from_dict(response.json())

        return response_401

    if response.status_code == 404:
        response_404 = Problem.from_dict(response.json())

        return response_404

    if response.status_code == 429:
        response_429 = Problem.from_dict(response.json())

        return response_429

    if client.raise_on_unexpected_status:
        raise errors.UnexpectedStatus(response.status_code, response.content)
    else:
        return None


def _build_response(
    *, client: AuthenticatedClient | Client, response: httpx.Response
) -> Response[PostV1VolumesIdQueryResponse200 | Problem]:
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
    body: PostV1VolumesIdQueryBodyType0 | PostV1VolumesIdQueryBodyType1,
) -> Response[PostV1VolumesIdQueryResponse200 | Problem]:
    """Batched point and ray queries (world coordinates)

     A point's voxel is floor((p - origin) / voxel_size); outside the grid is empty. A ray
    origin + t * direction (t >= 0, direction normalised) reports the solid voxels it crosses,
    where it first enters and last leaves solid, and its length inside solid (thickness).
    At least one and at most 100000 points and rays together.

    Args:
        id (str):
        body (PostV1VolumesIdQueryBodyType0 | PostV1VolumesIdQueryBodyType1): at least one point
            or ray

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Response[PostV1VolumesIdQueryResponse200 | Problem]
    """

    kwargs = _get_kwargs(
        id=id,
        body=body,
    )

    response = client.get_httpx_client().request(
        **kwargs,
    )

    return _build_response(client=client, response=response)


def sync(
    id: str,
    *,
    client: AuthenticatedClient | Client,
    body: PostV1VolumesIdQueryBodyType0 | PostV1VolumesIdQueryBodyType1,
) -> PostV1VolumesIdQueryResponse200 | Problem | None:
    """Batched point and ray queries (world coordinates)

     A point's voxel is floor((p - origin) / voxel_size); outside the grid is empty. A ray
    origin + t * direction (t >= 0, direction normalised) reports the solid voxels it crosses,
    where it first enters and last leaves solid, and its length inside solid (thickness).
    At least one and at most 100000 points and rays together.

    Args:
        id (str):
        body (PostV1VolumesIdQueryBodyType0 | PostV1VolumesIdQueryBodyType1): at least one point
            or ray

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        PostV1VolumesIdQueryResponse200 | Problem
    """

    return sync_detailed(
        id=id,
        client=client,
        body=body,
    ).parsed


async def asyncio_detailed(
    id: str,
    *,
    client: AuthenticatedClient | Client,
    body: PostV1VolumesIdQueryBodyType0 | PostV1VolumesIdQueryBodyType1,
) -> Response[PostV1VolumesIdQueryResponse200 | Problem]:
    """Batched point and ray queries (world coordinates)

     A point's voxel is floor((p - origin) / voxel_size); outside the grid is empty. A ray
    origin + t * direction (t >= 0, direction normalised) reports the solid voxels it crosses,
    where it first enters and last leaves solid, and its length inside solid (thickness).
    At least one and at most 100000 points and rays together.

    Args:
        id (str):
        body (PostV1VolumesIdQueryBodyType0 | PostV1VolumesIdQueryBodyType1): at least one point
            or ray

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Response[PostV1VolumesIdQueryResponse200 | Problem]
    """

    kwargs = _get_kwargs(
        id=id,
        body=body,
    )

    response = await client.get_async_httpx_client().request(**kwargs)

    return _build_response(client=client, response=response)


async def asyncio(
    id: str,
    *,
    client: AuthenticatedClient | Client,
    body: PostV1VolumesIdQueryBodyType0 | PostV1VolumesIdQueryBodyType1,
) -> PostV1VolumesIdQueryResponse200 | Problem | None:
    """Batched point and ray queries (world coordinates)

     A point's voxel is floor((p - origin) / voxel_size); outside the grid is empty. A ray
    origin + t * direction (t >= 0, direction normalised) reports the solid voxels it crosses,
    where it first enters and last leaves solid, and its length inside solid (thickness).
    At least one and at most 100000 points and rays together.

    Args:
        id (str):
        body (PostV1VolumesIdQueryBodyType0 | PostV1VolumesIdQueryBodyType1): at least one point
            or ray

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        PostV1VolumesIdQueryResponse200 | Problem
    """

    return (
        await asyncio_detailed(
            id=id,
            client=client,
            body=body,
        )
    ).parsed
