from http import HTTPStatus
from typing import Any

import httpx

from ... import errors
from ...client import AuthenticatedClient, Client
from ...models.job import Job
from ...models.post_v1_voxelize_band_type_1 import PostV1VoxelizeBandType1
from ...models.post_v1_voxelize_content_encoding import PostV1VoxelizeContentEncoding
from ...models.post_v1_voxelize_density_factor import PostV1VoxelizeDensityFactor
from ...models.post_v1_voxelize_fill import PostV1VoxelizeFill
from ...models.post_v1_voxelize_format import PostV1VoxelizeFormat
from ...models.post_v1_voxelize_method import PostV1VoxelizeMethod
from ...models.problem import Problem
from ...models.volume import Volume
from ...types import UNSET, File, Response, Unset


def _get_kwargs(
    *,
    body: File,
    method: PostV1VoxelizeMethod | Unset = PostV1VoxelizeMethod.SOLID,
    density_factor: PostV1VoxelizeDensityFactor | Unset = UNSET,
    thickness: float | Unset = UNSET,
    band: int | PostV1VoxelizeBandType1 | Unset = UNSET,
    resolution: int | Unset = UNSET,
    voxel_size: float | Unset = UNSET,
    origin: str | Unset = UNSET,
    dims: str | Unset = UNSET,
    cubic: bool | Unset = UNSET,
    padding: int | Unset = 0,
    color: bool | Unset = UNSET,
    material: bool | Unset = UNSET,
    fill: PostV1VoxelizeFill | Unset = UNSET,
    name: str | Unset = UNSET,
    wait: float | Unset = 0.0,
    format_: PostV1VoxelizeFormat | Unset = UNSET,
    max_voxels: int | Unset = UNSET,
    content_encoding: PostV1VoxelizeContentEncoding | Unset = UNSET,
) -> dict[str, Any]:
    headers: dict[str, Any] = {}
    if not isinstance(content_encoding, Unset):
        headers["Content-Encoding"] = str(content_encoding)

    params: dict[str, Any] = {}

    json_method: str | Unset = UNSET
    if not isinstance(method, Unset):
        json_method = method.value

    params["method"] = json_method

    json_density_factor: int | Unset = UNSET
    if not isinstance(density_factor, Unset):
        json_density_factor = density_factor.value

    params["density_factor"] = json_density_factor

    params["thickness"] = thickness

    json_band: int | str | Unset
    if isinstance(band, Unset):
        json_band = UNSET
    elif isinstance(band, PostV1VoxelizeBandType1):
        json_band = band.value
    else:
        json_band = band
    params["band"] = json_band

    params["resolution"] = resolution

    params["voxel_size"] = voxel_size

    params["origin"] = origin

    params["dims"] = dims

    params["cubic"] = cubic

    params["padding"] = padding

    params["color"] = color

    params["material"] = material

    json_fill: str | Unset = UNSET
    if not isinstance(fill, Unset):
        json_fill = fill.value

    params["fill"] = json_fill

    params["name"] = name

    params["wait"] = wait

    json_format_: str | Unset = UNSET
    if not isinstance(format_, Unset):
        json_format_ = format_.value

    params["format"] = json_format_

    params["max_voxels"] = max_voxels

    params = {k: v for k, v in params.items() if v is not UNSET and v is not None}

    _kwargs: dict[str, Any] = {
        "method": "post",
        "url": "/v1/voxelize",
        "params": params,
    }

    _kwargs["content"] = body.payload
    headers["Content-Type"] = "application/octet-stream"

    _kwargs["headers"] = headers
    return _kwargs


def _parse_response(
    *, client: AuthenticatedClient | Client, response: httpx.Response
) -> Job | Problem | Volume | None:
    if response.status_code == 201:
        response_201 = Volume.from_dict(response.json())

        return response_201

    if response.status_code == 202:
        response_202 = Job.from_dict(response.json())

        return response_202

    if response.status_code == 400:
        response_400 = Problem.from_dict(response.json())

        return response_400

    if response.status_code == 401:
        response_401 = Problem.from_dict(response.json())

        return response_401

    if response.status_code == 403:
        response_403 = Problem.from_dict(response.json())

        return response_403

    if response.status_code == 413:
        response_413 = Problem.from_dict(response.json())

        return response_413

    if response.status_code == 415:
        response_415 = Problem.from_dict(response.json())

        return response_415

    if response.status_code == 422:
        response_422 = Problem.from_dict(response.json())

        return response_422

    if response.status_code == 429:
        response_429 = Problem.from_dict(response.json())

        return response_429

    if response.status_code == 500:
        response_500 = Problem.from_dict(response.json())

        return response_500

    if response.status_code == 503:
        response_503 = Problem.from_dict(response.json())

        return response_503

    if response.status_code == 507:
        response_507 = Problem.from_dict(response.json())

        return response_507

    if client.raise_on_unexpected_status:
        raise errors.UnexpectedStatus(response.status_code, response.content)
    else:
        return None


def _build_response(
    *, client: AuthenticatedClient | Client, response: httpx.Response
) -> Response[Job | Problem | Volume]:
    return Response(
        status_code=HTTPStatus(response.status_code),
        content=response.content,
        headers=response.headers,
        parsed=_parse_response(client=client, response=response),
    )


def sync_detailed(
    *,
    client: AuthenticatedClient | Client,
    body: File,
    method: PostV1VoxelizeMethod | Unset = PostV1VoxelizeMethod.SOLID,
    density_factor: PostV1VoxelizeDensityFactor | Unset = UNSET,
    thickness: float | Unset = UNSET,
    band: int | PostV1VoxelizeBandType1 | Unset = UNSET,
    resolution: int | Unset = UNSET,
    voxel_size: float | Unset = UNSET,
    origin: str | Unset = UNSET,
    dims: str | Unset = UNSET,
    cubic: bool | Unset = UNSET,
    padding: int | Unset = 0,
    color: bool | Unset = UNSET,
    material: bool | Unset = UNSET,
    fill: PostV1VoxelizeFill | Unset = UNSET,
    name: str | Unset = UNSET,
    wait: float | Unset = 0.0,
    format_: PostV1VoxelizeFormat | Unset = UNSET,
    max_voxels: int | Unset = UNSET,
    content_encoding: PostV1VoxelizeContentEncoding | Unset = UNSET,
) -> Response[Job | Problem | Volume]:
    """Voxelize a mesh (the body is the mesh file)

    Args:
        method (PostV1VoxelizeMethod | Unset):  Default: PostV1VoxelizeMethod.SOLID.
        density_factor (PostV1VoxelizeDensityFactor | Unset):
        thickness (float | Unset):
        band (int | PostV1VoxelizeBandType1 | Unset):
        resolution (int | Unset):
        voxel_size (float | Unset): world units per voxel; a positive normal number
        origin (str | Unset):  Example: 0,0,0.
        dims (str | Unset):  Example: 64,64,64.
        cubic (bool | Unset):
        padding (int | Unset):  Default: 0.
        color (bool | Unset):
        material (bool | Unset):
        fill (PostV1VoxelizeFill | Unset):
        name (str | Unset): at most 256 characters, none of them control characters
        wait (float | Unset):  Default: 0.0.
        format_ (PostV1VoxelizeFormat | Unset):
        max_voxels (int | Unset):
        content_encoding (PostV1VoxelizeContentEncoding | Unset):
        body (File):

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Response[Job | Problem | Volume]
    """

    kwargs = _get_kwargs(
        body=body,
        method=method,
        density_factor=density_factor,
        thickness=thickness,
        band=band,
        resolution=resolution,
        voxel_size=voxel_size,
        origin=origin,
        dims=dims,
        cubic=cubic,
        padding=padding,
        color=color,
        material=material,
        fill=fill,
        name=name,
        wait=wait,
        format_=format_,
        max_voxels=max_voxels,
        content_encoding=content_encoding,
    )

    response = client.get_httpx_client().request(
        **kwargs,
    )

    return _build_response(client=client, response=response)


def sync(
    *,
    client: AuthenticatedClient | Client,
    body: File,
    method: PostV1VoxelizeMethod | Unset = PostV1VoxelizeMethod.SOLID,
    density_factor: PostV1VoxelizeDensityFactor | Unset = UNSET,
    thickness: float | Unset = UNSET,
    band: int | PostV1VoxelizeBandType1 | Unset = UNSET,
    resolution: int | Unset = UNSET,
    voxel_size: float | Unset = UNSET,
    origin: str | Unset = UNSET,
    dims: str | Unset = UNSET,
    cubic: bool | Unset = UNSET,
    padding: int | Unset = 0,
    color: bool | Unset = UNSET,
    material: bool | Unset = UNSET,
    fill: PostV1VoxelizeFill | Unset = UNSET,
    name: str | Unset = UNSET,
    wait: float | Unset = 0.0,
    format_: PostV1VoxelizeFormat | Unset = UNSET,
    max_voxels: int | Unset = UNSET,
    content_encoding: PostV1VoxelizeContentEncoding | Unset = UNSET,
) -> Job | Problem | Volume | None:
    """Voxelize a mesh (the body is the mesh file)

    Args:
        method (PostV1VoxelizeMethod | Unset):  Default: PostV1VoxelizeMethod.SOLID.
        density_factor (PostV1VoxelizeDensityFactor | Unset):
        thickness (float | Unset):
        band (int | PostV1VoxelizeBandType1 | Unset):
        resolution (int | Unset):
        voxel_size (float | Unset): world units per voxel; a positive normal number
        origin (str | Unset):  Example: 0,0,0.
        dims (str | Unset):  Example: 64,64,64.
        cubic (bool | Unset):
        padding (int | Unset):  Default: 0.
        color (bool | Unset):
        material (bool | Unset):
        fill (PostV1VoxelizeFill | Unset):
        name (str | Unset): at most 256 characters, none of them control characters
        wait (float | Unset):  Default: 0.0.
        format_ (PostV1VoxelizeFormat | Unset):
        max_voxels (int | Unset):
        content_encoding (PostV1VoxelizeContentEncoding | Unset):
        body (File):

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Job | Problem | Volume
    """

    return sync_detailed(
        client=client,
        body=body,
        method=method,
        density_factor=density_factor,
        thickness=thickness,
        band=band,
        resolution=resolution,
        voxel_size=voxel_size,
        origin=origin,
        dims=dims,
        cubic=cubic,
        padding=padding,
        color=color,
        material=material,
        fill=fill,
        name=name,
        wait=wait,
        format_=format_,
        max_voxels=max_voxels,
        content_encoding=content_encoding,
    ).parsed


async def asyncio_detailed(
    *,
    client: AuthenticatedClient | Client,
    body: File,
    method: PostV1VoxelizeMethod | Unset = PostV1VoxelizeMethod.SOLID,
    density_factor: PostV1VoxelizeDensityFactor | Unset = UNSET,
    thickness: float | Unset = UNSET,
    band: int | PostV1VoxelizeBandType1 | Unset = UNSET,
    resolution: int | Unset = UNSET,
    voxel_size: float | Unset = UNSET,
    origin: str | Unset = UNSET,
    dims: str | Unset = UNSET,
    cubic: bool | Unset = UNSET,
    padding: int | Unset = 0,
    color: bool | Unset = UNSET,
    material: bool | Unset = UNSET,
    fill: PostV1VoxelizeFill | Unset = UNSET,
    name: str | Unset = UNSET,
    wait: float | Unset = 0.0,
    format_: PostV1VoxelizeFormat | Unset = UNSET,
    max_voxels: int | Unset = UNSET,
    content_encoding: PostV1VoxelizeContentEncoding | Unset = UNSET,
) -> Response[Job | Problem | Volume]:
    """Voxelize a mesh (the body is the mesh file)

    Args:
        method (PostV1VoxelizeMethod | Unset):  Default: PostV1VoxelizeMethod.SOLID.
        density_factor (PostV1VoxelizeDensityFactor | Unset):
        thickness (float | Unset):
        band (int | PostV1VoxelizeBandType1 | Unset):
        resolution (int | Unset):
        voxel_size (float | Unset): world units per voxel; a positive normal number
        origin (str | Unset):  Example: 0,0,0.
        dims (str | Unset):  Example: 64,64,64.
        cubic (bool | Unset):
        padding (int | Unset):  Default: 0.
        color (bool | Unset):
        material (bool | Unset):
        fill (PostV1VoxelizeFill | Unset):
        name (str | Unset): at most 256 characters, none of them control characters
        wait (float | Unset):  Default: 0.0.
        format_ (PostV1VoxelizeFormat | Unset):
        max_voxels (int | Unset):
        content_encoding (PostV1VoxelizeContentEncoding | Unset):
        body (File):

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Response[Job | Problem | Volume]
    """

    kwargs = _get_kwargs(
        body=body,
        method=method,
        density_factor=density_factor,
        thickness=thickness,
        band=band,
        resolution=resolution,
        voxel_size=voxel_size,
        origin=origin,
        dims=dims,
        cubic=cubic,
        padding=padding,
        color=color,
        material=material,
        fill=fill,
        name=name,
        wait=wait,
        format_=format_,
        max_voxels=max_voxels,
        content_encoding=content_encoding,
    )

    response = await client.get_async_httpx_client().request(**kwargs)

    return _build_response(client=client, response=response)


async def asyncio(
    *,
    client: AuthenticatedClient | Client,
    body: File,
    method: PostV1VoxelizeMethod | Unset = PostV1VoxelizeMethod.SOLID,
    density_factor: PostV1VoxelizeDensityFactor | Unset = UNSET,
    thickness: float | Unset = UNSET,
    band: int | PostV1VoxelizeBandType1 | Unset = UNSET,
    resolution: int | Unset = UNSET,
    voxel_size: float | Unset = UNSET,
    origin: str | Unset = UNSET,
    dims: str | Unset = UNSET,
    cubic: bool | Unset = UNSET,
    padding: int | Unset = 0,
    color: bool | Unset = UNSET,
    material: bool | Unset = UNSET,
    fill: PostV1VoxelizeFill | Unset = UNSET,
    name: str | Unset = UNSET,
    wait: float | Unset = 0.0,
    format_: PostV1VoxelizeFormat | Unset = UNSET,
    max_voxels: int | Unset = UNSET,
    content_encoding: PostV1VoxelizeContentEncoding | Unset = UNSET,
) -> Job | Problem | Volume | None:
    """Voxelize a mesh (the body is the mesh file)

    Args:
        method (PostV1VoxelizeMethod | Unset):  Default: PostV1VoxelizeMethod.SOLID.
        density_factor (PostV1VoxelizeDensityFactor | Unset):
        thickness (float | Unset):
        band (int | PostV1VoxelizeBandType1 | Unset):
        resolution (int | Unset):
        voxel_size (float | Unset): world units per voxel; a positive normal number
        origin (str | Unset):  Example: 0,0,0.
        dims (str | Unset):  Example: 64,64,64.
        cubic (bool | Unset):
        padding (int | Unset):  Default: 0.
        color (bool | Unset):
        material (bool | Unset):
        fill (PostV1VoxelizeFill | Unset):
        name (str | Unset): at most 256 characters, none of them control characters
        wait (float | Unset):  Default: 0.0.
        format_ (PostV1VoxelizeFormat | Unset):
        max_voxels (int | Unset):
        content_encoding (PostV1VoxelizeContentEncoding | Unset):
        body (File):

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Job | Problem | Volume
    """

    return (
        await asyncio_detailed(
            client=client,
            body=body,
            method=method,
            density_factor=density_factor,
            thickness=thickness,
            band=band,
            resolution=resolution,
            voxel_size=voxel_size,
            origin=origin,
            dims=dims,
            cubic=cubic,
            padding=padding,
            color=color,
            material=material,
            fill=fill,
            name=name,
            wait=wait,
            format_=format_,
            max_voxels=max_voxels,
            content_encoding=content_encoding,
        )
    ).parsed
