from http import HTTPStatus
from typing import Any
from urllib.parse import quote

import httpx

from ... import errors
from ...client import AuthenticatedClient, Client
from ...models.get_v1_volumes_id_normals_response_200 import (
    GetV1VolumesIdNormalsResponse200,
)
from ...models.problem import Problem
from ...types import UNSET, Response


def _get_kwargs(
    id: str,
    *,
    points: str,
) -> dict[str, Any]:

    params: dict[str, Any] = {}

    params["points"] = points

    params = {k: v for k, v in params.items() if v is not UNSET and v is not None}

    _kwargs: dict[str, Any] = {
        "method": "get",
        "url": "/v1/volumes/{id}/normals".format(
            id=quote(str(id), safe=""),
        ),
        "params": params,
    }

    return _kwargs


def _parse_response(
    *, client: AuthenticatedClient | Client, response: httpx.Response
) -> GetV1VolumesIdNormalsResponse200 | Problem | None:
    if response.status_code == 200:
        response_200 = GetV1VolumesIdNormalsResponse200.from_dict(response.json())

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
) -> Response[GetV1VolumesIdNormalsResponse200 | Problem]:
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
    points: str,
) -> Response[GetV1VolumesIdNormalsResponse200 | Problem]:
    """Outward normals from the density gradient (central differences; null where it vanishes)

    Args:
        id (str):
        points (str):  Example: 0.1,0.2,0.3;1,2,3.

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Response[GetV1VolumesIdNormalsResponse200 | Problem]
    """

    kwargs = _get_kwargs(
        id=id,
        points=points,
    )

    response = client.get_httpx_client().request(
        **kwargs,
    )

    return _build_response(client=client, response=response)


def sync(
    id: str,
    *,
    client: AuthenticatedClient | Client,
    points: str,
) -> GetV1VolumesIdNormalsResponse200 | Problem | None:
    """Outward normals from the density gradient (central differences; null where it vanishes)

    Args:
        id (str):
        points (str):  Example: 0.1,0.2,0.3;1,2,3.

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        GetV1VolumesIdNormalsResponse200 | Problem
    """

    return sync_detailed(
        id=id,
        client=client,
        points=points,
    ).parsed


async def asyncio_detailed(
    id: str,
    *,
    client: AuthenticatedClient | Client,
    points: str,
) -> Response[GetV1VolumesIdNormalsResponse200 | Problem]:
    """Outward normals from the density gradient (central differences; null where it vanishes)

    Args:
        id (str):
        points (str):  Example: 0.1,0.2,0.3;1,2,3.

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Response[GetV1VolumesIdNormalsResponse200 | Problem]
    """

    kwargs = _get_kwargs(
        id=id,
        points=points,
    )

    response = await client.get_async_httpx_client().request(**kwargs)

    return _build_response(client=client, response=response)


async def asyncio(
    id: str,
    *,
    client: AuthenticatedClient | Client,
    points: str,
) -> GetV1VolumesIdNormalsResponse200 | Problem | None:
    """Outward normals from the density gradient (central differences; null where it vanishes)

    Args:
        id (str):
        points (str):  Example: 0.1,0.2,0.3;1,2,3.

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        GetV1VolumesIdNormalsResponse200 | Problem
    """

    return (
        await asyncio_detailed(
            id=id,
            client=client,
            points=points,
        )
    ).parsed
