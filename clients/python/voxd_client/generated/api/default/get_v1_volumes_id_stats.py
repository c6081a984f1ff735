from http import HTTPStatus
from typing import Any
from urllib.parse import quote

import httpx

from ... import errors
from ...client import AuthenticatedClient, Client
from ...models.bit_stats import BitStats
from ...models.distance_stats import DistanceStats
from ...models.problem import Problem
from ...types import Response


def _get_kwargs(
    id: str,
) -> dict[str, Any]:

    _kwargs: dict[str, Any] = {
        "method": "get",
        "url": "/v1/volumes/{id}/stats".format(
            id=quote(str(id), safe=""),
        ),
    }

    return _kwargs


def _parse_response(
    *, client: AuthenticatedClient | Client, response: httpx.Response
) -> BitStats | DistanceStats | Problem | None:
    if response.status_code == 200:

        def _parse_response_200(data: object) -> BitStats | DistanceStats:
            try:
                if not isinstance(data, dict):
                    raise TypeError()
                response_200_type_0 = BitStats.from_dict(data)

                return response_200_type_0
            except (TypeError, ValueError, AttributeError, KeyError):
                pass
            if not isinstance(data, dict):
                raise TypeError()
            response_200_type_1 = DistanceStats.from_dict(data)

            return response_200_type_1

        response_200 = _parse_response_200(response.json())

        return response_200

    if response.status_code == 401:
        response_401 = Problem.from_dict(response.json())

        return response_401

    if response.status_code == 404:
        response_404 = Problem.from_dict(response.json())

        return response_404

    if response.status_code == 422:
        response_422 = Problem.from_dict(response.json())

        return response_422

    if response.status_code == 429:
        response_429 = Problem.from_dict(response.json())

        return response_429

    if client.raise_on_unexpected_status:
        raise errors.UnexpectedStatus(response.status_code, response.content)
    else:
        return None


def _build_response(
    *, client: AuthenticatedClient | Client, response: httpx.Response
) -> Response[BitStats | DistanceStats | Problem]:
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
) -> Response[BitStats | DistanceStats | Problem]:
    """Statistics of a stored bit or distance volume

     Distance volumes answer DistanceStats (docs/methods.md, "Operations on distance volumes").
    For bit volumes: voxels are unit-density cubes. surface_voxels are solid voxels with an empty face
    neighbour
    (outside the grid counts as empty); components are 6- and 26-connected; the inertia tensor
    is about the centre of mass, in world units. Bounds are [min, max] pairs.

    Args:
        id (str):

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Response[BitStats | DistanceStats | Problem]
    """

    kwargs = _get_kwargs(
        id=id,
    )

    response = client.get_httpx_client().request(
        **kwargs,
    )

    return _build_response(client=client, response=response)


def sync(
    id: str,
    *,
    client: AuthenticatedClient | Client,
) -> BitStats | DistanceStats | Problem | None:
    """Statistics of a stored bit or distance volume

     Distance volumes answer DistanceStats (docs/methods.md, "Operations on distance volumes").
    For bit volumes: voxels are unit-density cubes. surface_voxels are solid voxels with an empty face
    neighbour
    (outside the grid counts as empty); components are 6- and 26-connected; the inertia tensor
    is about the centre of mass, in world units. Bounds are [min, max] pairs.

    Args:
        id (str):

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        BitStats | DistanceStats | Problem
    """

    return sync_detailed(
        id=id,
        client=client,
    ).parsed


async def asyncio_detailed(
    id: str,
    *,
    client: AuthenticatedClient | Client,
) -> Response[BitStats | DistanceStats | Problem]:
    """Statistics of a stored bit or distance volume

     Distance volumes answer DistanceStats (docs/methods.md, "Operations on distance volumes").
    For bit volumes: voxels are unit-density cubes. surface_voxels are solid voxels with an empty face
    neighbour
    (outside the grid counts as empty); components are 6- and 26-connected; the inertia tensor
    is about the centre of mass, in world units. Bounds are [min, max] pairs.

    Args:
        id (str):

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Response[BitStats | DistanceStats | Problem]
    """

    kwargs = _get_kwargs(
        id=id,
    )

    response = await client.get_async_httpx_client().request(**kwargs)

    return _build_response(client=client, response=response)


async def asyncio(
    id: str,
    *,
    client: AuthenticatedClient | Client,
) -> BitStats | DistanceStats | Problem | None:
    """Statistics of a stored bit or distance volume

     Distance volumes answer DistanceStats (docs/methods.md, "Operations on distance volumes").
    For bit volumes: voxels are unit-density cubes. surface_voxels are solid voxels with an empty face
    neighbour
    (outside the grid counts as empty); components are 6- and 26-connected; the inertia tensor
    is about the centre of mass, in world units. Bounds are [min, max] pairs.

    Args:
        id (str):

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        BitStats | DistanceStats | Problem
    """

    return (
        await asyncio_detailed(
            id=id,
            client=client,
        )
    ).parsed
