from http import HTTPStatus
from typing import Any
from urllib.parse import quote

import httpx

from ... import errors
from ...client import AuthenticatedClient, Client
from ...models.problem import Problem
from ...types import Response


def _get_kwargs(
    id: str,
) -> dict[str, Any]:

    _kwargs: dict[str, Any] = {
        "method": "get",
        "url": "/v1/volumes/{id}/view".format(
            id=quote(str(id), safe=""),
        ),
    }

    return _kwargs


def _parse_response(
    *, client: AuthenticatedClient | Client, response: httpx.Response
) -> Problem | str | None:
    if response.status_code == 200:
        response_200 = response.text
        return response_200

    if response.status_code == 404:
        response_404 = Problem.from_dict(response.json())

        return response_404

    if client.raise_on_unexpected_status:
        raise errors.UnexpectedStatus(response.status_code, response.content)
    else:
        return None


def _build_response(
    *, client: AuthenticatedClient | Client, response: httpx.Response
) -> Response[Problem | str]:
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
) -> Response[Problem | str]:
    """A page that shows the volume in 3D (its extracted mesh, rotate and zoom, an algorithm switch), its
    grid and counts, and a slice slider over the PNG previews

     A static page (three.js, served from the binary by /v1/viewer/{file}: no internet needed) that
    fetches the volume through this API. It needs no key itself; where the service asks for keys, give
    yours after #key= in the page's address (the fragment is never sent) and the page sends it with its
    requests. ?algorithm= picks the first mesh (default surface-nets).

    Args:
        id (str):

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Response[Problem | str]
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
) -> Problem | str | None:
    """A page that shows the volume in 3D (its extracted mesh, rotate and zoom, an algorithm switch), its
    grid and counts, and a slice slider over the PNG previews

     A static page (three.js, served from the binary by /v1/viewer/{file}: no internet needed) that
    fetches the volume through this API. It needs no key itself; where the service asks for keys, give
    yours after #key= in the page's address (the fragment is never sent) and the page sends it with its
    requests. ?algorithm= picks the first mesh (default surface-nets).

    Args:
        id (str):

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Problem | str
    """

    return sync_detailed(
        id=id,
        client=client,
    ).parsed


async def asyncio_detailed(
    id: str,
    *,
    client: AuthenticatedClient | Client,
) -> Response[Problem | str]:
    """A page that shows the volume in 3D (its extracted mesh, rotate and zoom, an algorithm switch), its
    grid and counts, and a slice slider over the PNG previews

     A static page (three.js, served from the binary by /v1/viewer/{file}: no internet needed) that
    fetches the volume through this API. It needs no key itself; where the service asks for keys, give
    yours after #key= in the page's address (the fragment is never sent) and the page sends it with its
    requests. ?algorithm= picks the first mesh (default surface-nets).

    Args:
        id (str):

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Response[Problem | str]
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
) -> Problem | str | None:
    """A page that shows the volume in 3D (its extracted mesh, rotate and zoom, an algorithm switch), its
    grid and counts, and a slice slider over the PNG previews

     A static page (three.js, served from the binary by /v1/viewer/{file}: no internet needed) that
    fetches the volume through this API. It needs no key itself; where the service asks for keys, give
    yours after #key= in the page's address (the fragment is never sent) and the page sends it with its
    requests. ?algorithm= picks the first mesh (default surface-nets).

    Args:
        id (str):

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Problem | str
    """

    return (
        await asyncio_detailed(
            id=id,
            client=client,
        )
    ).parsed
