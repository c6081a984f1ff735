from http import HTTPStatus
from typing import Any

import httpx

from ... import errors
from ...client import AuthenticatedClient, Client
from ...models.csg_expression import CsgExpression
from ...models.problem import Problem
from ...models.volume import Volume
from ...types import UNSET, Response, Unset


def _get_kwargs(
    *,
    body: CsgExpression | str,
    name: str | Unset = UNSET,
) -> dict[str, Any]:
    headers: dict[str, Any] = {}

    params: dict[str, Any] = {}

    params["name"] = name

    params = {k: v for k, v in params.items() if v is not UNSET and v is not None}

    _kwargs: dict[str, Any] = {
        "method": "post",
        "url": "/v1/volumes/csg",
        "params": params,
    }

    if isinstance(body, CsgExpression):
        _kwargs["json"] = body.to_dict()
    else:
        _kwargs["json"] = body

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
    *,
    client: AuthenticatedClient | Client,
    body: CsgExpression | str,
    name: str | Unset = UNSET,
) -> Response[Problem | Volume]:
    """Combine stored bit volumes with union, intersection, difference, xor (n-ary), stored as a new volume

     The body is an expression: a volume id, or {"op": "union|intersection|difference|xor",
    "operands": [expression, ...]}. Grids must be aligned (equal voxel size, origins a whole
    number of voxels apart); the result's grid is the operands' bounding grid for union and
    xor, their overlap for intersection, and the first operand's for difference. The
    expression is kept as the volume's provenance.
    Volumes with channels (color, material) combine with each other and with bit volumes:
    a result voxel takes each channel from the first operand, in the expression's order,
    set there with that channel (rgba (0, 0, 0, 0) and material "none" where only a bit
    volume covers it); the operands' material tables are merged into one (equal name and
    base colour shared), ids renumbered (docs/methods.md, "Colour and material").
    Distance volumes combine with each other only (a bit volume among them is
    wrong-volume-kind), on one grid (else misaligned-grids), by min (union), max
    (intersection) and max(a, -b) (difference); xor is invalid-parameter. Operands are
    clamped to the narrowest band first; the result is a sparse distance volume
    (docs/methods.md, "Operations on distance volumes").

    Args:
        name (str | Unset): at most 256 characters, none of them control characters
        body (CsgExpression | str): a volume id, or an expression

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Response[Problem | Volume]
    """

    kwargs = _get_kwargs(
        body=body,
        name=name,
    )

    response = client.get_httpx_client().request(
        **kwargs,
    )

    return _build_response(client=client, response=response)


def sync(
    *,
    client: AuthenticatedClient | Client,
    body: CsgExpression | str,
    name: str | Unset = UNSET,
) -> Problem | Volume | None:
    """Combine stored bit volumes with union, intersection, difference, xor (n-ary), stored as a new volume

     The body is an expression: a volume id, or {"op": "union|intersection|difference|xor",
    "operands": [expression, ...]}. Grids must be aligned (equal voxel size, origins a whole
    number of voxels apart); the result's grid is the operands' bounding grid for union and
    xor, their overlap for intersection, and the first operand's for difference. The
    expression is kept as the volume's provenance.
    Volumes with channels (color, material) combine with each other and with bit volumes:
    a result voxel takes each channel from the first operand, in the expression's order,
    set there with that channel (rgba (0, 0, 0, 0) and material "none" where only a bit
    volume covers it); the operands' material tables are merged into one (equal name and
    base colour shared), ids renumbered (docs/methods.md, "Colour and material").
    Distance volumes combine with each other only (a bit volume among them is
    wrong-volume-kind), on one grid (else misaligned-grids), by min (union), max
    (intersection) and max(a, -b) (difference); xor is invalid-parameter. Operands are
    clamped to the narrowest band first; the result is a sparse distance volume
    (docs/methods.md, "Operations on distance volumes").

    Args:
        name (str | Unset): at most 256 characters, none of them control characters
        body (CsgExpression | str): a volume id, or an expression

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Problem | Volume
    """

    return sync_detailed(
        client=client,
        body=body,
        name=name,
    ).parsed


async def asyncio_detailed(
    *,
    client: AuthenticatedClient | Client,
    body: CsgExpression | str,
    name: str | Unset = UNSET,
) -> Response[Problem | Volume]:
    """Combine stored bit volumes with union, intersection, difference, xor (n-ary), stored as a new volume

     The body is an expression: a volume id, or {"op": "union|intersection|difference|xor",
    "operands": [expression, ...]}. Grids must be aligned (equal voxel size, origins a whole
    number of voxels apart); the result's grid is the operands' bounding grid for union and
    xor, their overlap for intersection, and the first operand's for difference. The
    expression is kept as the volume's provenance.
    Volumes with channels (color, material) combine with each other and with bit volumes:
    a result voxel takes each channel from the first operand, in the expression's order,
    set there with that channel (rgba (0, 0, 0, 0) and material "none" where only a bit
    volume covers it); the operands' material tables are merged into one (equal name and
    base colour shared), ids renumbered (docs/methods.md, "Colour and material").
    Distance volumes combine with each other only (a bit volume among them is
    wrong-volume-kind), on one grid (else misaligned-grids), by min (union), max
    (intersection) and max(a, -b) (difference); xor is invalid-parameter. Operands are
    clamped to the narrowest band first; the result is a sparse distance volume
    (docs/methods.md, "Operations on distance volumes").

    Args:
        name (str | Unset): at most 256 characters, none of them control characters
        body (CsgExpression | str): a volume id, or an expression

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Response[Problem | Volume]
    """

    kwargs = _get_kwargs(
        body=body,
        name=name,
    )

    response = await client.get_async_httpx_client().request(**kwargs)

    return _build_response(client=client, response=response)


async def asyncio(
    *,
    client: AuthenticatedClient | Client,
    body: CsgExpression | str,
    name: str | Unset = UNSET,
) -> Problem | Volume | None:
    """Combine stored bit volumes with union, intersection, difference, xor (n-ary), stored as a new volume

     The body is an expression: a volume id, or {"op": "union|intersection|difference|xor",
    "operands": [expression, ...]}. Grids must be aligned (equal voxel size, origins a whole
    number of voxels apart); the result's grid is the operands' bounding grid for union and
    xor, their overlap for intersection, and the first operand's for difference. The
    expression is kept as the volume's provenance.
    Volumes with channels (color, material) combine with each other and with bit volumes:
    a result voxel takes each channel from the first operand, in the expression's order,
    set there with that channel (rgba (0, 0, 0, 0) and material "none" where only a bit
    volume covers it); the operands' material tables are merged into one (equal name and
    base colour shared), ids renumbered (docs/methods.md, "Colour and material").
    Distance volumes combine with each other only (a bit volume among them is
    wrong-volume-kind), on one grid (else misaligned-grids), by min (union), max
    (intersection) and max(a, -b) (difference); xor is invalid-parameter. Operands are
    clamped to the narrowest band first; the result is a sparse distance volume
    (docs/methods.md, "Operations on distance volumes").

    Args:
        name (str | Unset): at most 256 characters, none of them control characters
        body (CsgExpression | str): a volume id, or an expression

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Problem | Volume
    """

    return (
        await asyncio_detailed(
            client=client,
            body=body,
            name=name,
        )
    ).parsed
