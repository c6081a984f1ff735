from http import HTTPStatus
from io import BytesIO
from typing import Any
from urllib.parse import quote

import httpx

from ... import errors
from ...client import AuthenticatedClient, Client
from ...models.get_v1_volumes_id_preview_png_axis import GetV1VolumesIdPreviewPngAxis
from ...models.get_v1_volumes_id_preview_png_projection import (
    GetV1VolumesIdPreviewPngProjection,
)
from ...models.problem import Problem
from ...types import UNSET, File, Response, Unset


def _get_kwargs(
    id: str,
    *,
    axis: GetV1VolumesIdPreviewPngAxis | Unset = GetV1VolumesIdPreviewPngAxis.Z,
    slice_: int | Unset = UNSET,
    projection: GetV1VolumesIdPreviewPngProjection | Unset = UNSET,
) -> dict[str, Any]:

    params: dict[str, Any] = {}

    json_axis: str | Unset = UNSET
    if not isinstance(axis, Unset):
        json_axis = axis.value

    params["axis"] = json_axis

    params["slice"] = slice_

    json_projection: str | Unset = UNSET
    if not isinstance(projection, Unset):
        json_projection = projection.value

    params["projection"] = json_projection

    params = {k: v for k, v in params.items() if v is not UNSET and v is not None}

    _kwargs: dict[str, Any] = {
        "method": "get",
        "url": "/v1/volumes/{id}/preview.png".format(
            id=quote(str(id), safe=""),
        ),
        "params": params,
    }

    return _kwargs


def _parse_response(
    *, client: AuthenticatedClient | Client, response: httpx.Response
) -> File | Problem | None:
    if response.status_code == 200:
        response_200 = File(payload=BytesIO(response.content))

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
) -> Response[File | Problem]:
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
    axis: GetV1VolumesIdPreviewPngAxis | Unset = GetV1VolumesIdPreviewPngAxis.Z,
    slice_: int | Unset = UNSET,
    projection: GetV1VolumesIdPreviewPngProjection | Unset = UNSET,
) -> Response[File | Problem]:
    """A grayscale picture of a slice or a projection (the second image axis points up)

    Args:
        id (str):
        axis (GetV1VolumesIdPreviewPngAxis | Unset):  Default: GetV1VolumesIdPreviewPngAxis.Z.
        slice_ (int | Unset):
        projection (GetV1VolumesIdPreviewPngProjection | Unset):

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Response[File | Problem]
    """

    kwargs = _get_kwargs(
        id=id,
        axis=axis,
        slice_=slice_,
        projection=projection,
    )

    response = client.get_httpx_client().request(
        **kwargs,
    )

    return _build_response(client=client, response=response)


def sync(
    id: str,
    *,
    client: AuthenticatedClient | Client,
    axis: GetV1VolumesIdPreviewPngAxis | Unset = GetV1VolumesIdPreviewPngAxis.Z,
    slice_: int | Unset = UNSET,
    projection: GetV1VolumesIdPreviewPngProjection | Unset = UNSET,
) -> File | Problem | None:
    """A grayscale picture of a slice or a projection (the second image axis points up)

    Args:
        id (str):
        axis (GetV1VolumesIdPreviewPngAxis | Unset):  Default: GetV1VolumesIdPreviewPngAxis.Z.
        slice_ (int | Unset):
        projection (GetV1VolumesIdPreviewPngProjection | Unset):

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        File | Problem
    """

    return sync_detailed(
        id=id,
        client=client,
        axis=axis,
        slice_=slice_,
        projection=projection,
    ).parsed


async def asyncio_detailed(
    id: str,
    *,
    client: AuthenticatedClient | Client,
    axis: GetV1VolumesIdPreviewPngAxis | Unset = GetV1VolumesIdPreviewPngAxis.Z,
    slice_: int | Unset = UNSET,
    projection: GetV1VolumesIdPreviewPngProjection | Unset = UNSET,
) -> Response[File | Problem]:
    """A grayscale picture of a slice or a projection (the second image axis points up)

    Args:
        id (str):
        axis (GetV1VolumesIdPreviewPngAxis | Unset):  Default: GetV1VolumesIdPreviewPngAxis.Z.
        slice_ (int | Unset):
        projection (GetV1VolumesIdPreviewPngProjection | Unset):

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Response[File | Problem]
    """

    kwargs = _get_kwargs(
        id=id,
        axis=axis,
        slice_=slice_,
        projection=projection,
    )

    response = await client.get_async_httpx_client().request(**kwargs)

    return _build_response(client=client, response=response)


async def asyncio(
    id: str,
    *,
    client: AuthenticatedClient | Client,
    axis: GetV1VolumesIdPreviewPngAxis | Unset = GetV1VolumesIdPreviewPngAxis.Z,
    slice_: int | Unset = UNSET,
    projection: GetV1VolumesIdPreviewPngProjection | Unset = UNSET,
) -> File | Problem | None:
    """A grayscale picture of a slice or a projection (the second image axis points up)

    Args:
        id (str):
        axis (GetV1VolumesIdPreviewPngAxis | Unset):  Default: GetV1VolumesIdPreviewPngAxis.Z.
        slice_ (int | Unset):
        projection (GetV1VolumesIdPreviewPngProjection | Unset):

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        File | Problem
    """

    return (
        await asyncio_detailed(
            id=id,
            client=client,
            axis=axis,
            slice_=slice_,
            projection=projection,
        )
    ).parsed
