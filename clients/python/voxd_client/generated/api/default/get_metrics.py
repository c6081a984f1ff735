from http import HTTPStatus
from typing import Any

import httpx

from ... import errors
from ...client import AuthenticatedClient, Client
from ...models.problem import Problem
from ...types import Response


def _get_kwargs() -> dict[str, Any]:

    _kwargs: dict[str, Any] = {
        "method": "get",
        "url": "/metrics",
    }

    return _kwargs


def _parse_response(
    *, client: AuthenticatedClient | Client, response: httpx.Response
) -> Problem | str | None:
    if response.status_code == 200:
        response_200 = response.text
        return response_200

    if response.status_code == 401:
        response_401 = Problem.from_dict(response.json())

        return response_401

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
    *,
    client: AuthenticatedClient | Client,
) -> Response[Problem | str]:
    """Prometheus metrics (voxd_jobs, voxd_queue_depth, voxd_queue_oldest_seconds, voxd_queue_running,
    voxd_queue_available, voxd_queue_class_depth, voxd_job_duration_seconds, voxd_voxels_total,
    voxd_voxels_per_second, voxd_engine_info; on the GPU engine voxd_gpu_submissions_total,
    voxd_gpu_slabs_total, voxd_gpu_submission_slabs_max, voxd_gpu_buffers_created_total,
    voxd_gpu_buffers_reused_total, voxd_gpu_pool_idle_bytes; with API keys voxd_key_requests_total,
    voxd_key_rate_limited_total, voxd_unauthorized_total)

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Response[Problem | str]
    """

    kwargs = _get_kwargs()

    response = client.get_httpx_client().request(
        **kwargs,
    )

    return _build_response(client=client, response=response)


def sync(
    *,
    client: AuthenticatedClient | Client,
) -> Problem | str | None:
    """Prometheus metrics (voxd_jobs, voxd_queue_depth, voxd_queue_oldest_seconds, voxd_queue_running,
    voxd_queue_available, voxd_queue_class_depth, voxd_job_duration_seconds, voxd_voxels_total,
    voxd_voxels_per_second, voxd_engine_info; on the GPU engine voxd_gpu_submissions_total,
    voxd_gpu_slabs_total, voxd_gpu_submission_slabs_max, voxd_gpu_buffers_created_total,
    voxd_gpu_buffers_reused_total, voxd_gpu_pool_idle_bytes; with API keys voxd_key_requests_total,
    voxd_key_rate_limited_total, voxd_unauthorized_total)

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Problem | str
    """

    return sync_detailed(
        client=client,
    ).parsed


async def asyncio_detailed(
    *,
    client: AuthenticatedClient | Client,
) -> Response[Problem | str]:
    """Prometheus metrics (voxd_jobs, voxd_queue_depth, voxd_queue_oldest_seconds, voxd_queue_running,
    voxd_queue_available, voxd_queue_class_depth, voxd_job_duration_seconds, voxd_voxels_total,
    voxd_voxels_per_second, voxd_engine_info; on the GPU engine voxd_gpu_submissions_total,
    voxd_gpu_slabs_total, voxd_gpu_submission_slabs_max, voxd_gpu_buffers_created_total,
    voxd_gpu_buffers_reused_total, voxd_gpu_pool_idle_bytes; with API keys voxd_key_requests_total,
    voxd_key_rate_limited_total, voxd_unauthorized_total)

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Response[Problem | str]
    """

    kwargs = _get_kwargs()

    response = await client.get_async_httpx_client().request(**kwargs)

    return _build_response(client=client, response=response)


async def asyncio(
    *,
    client: AuthenticatedClient | Client,
) -> Problem | str | None:
    """Prometheus metrics (voxd_jobs, voxd_queue_depth, voxd_queue_oldest_seconds, voxd_queue_running,
    voxd_queue_available, voxd_queue_class_depth, voxd_job_duration_seconds, voxd_voxels_total,
    voxd_voxels_per_second, voxd_engine_info; on the GPU engine voxd_gpu_submissions_total,
    voxd_gpu_slabs_total, voxd_gpu_submission_slabs_max, voxd_gpu_buffers_created_total,
    voxd_gpu_buffers_reused_total, voxd_gpu_pool_idle_bytes; with API keys voxd_key_requests_total,
    voxd_key_rate_limited_total, voxd_unauthorized_total)

    Raises:
        errors.UnexpectedStatus: If the server returns an undocumented status code and Client.raise_on_unexpected_status is True.
        httpx.TimeoutException: If the request takes longer than Client.timeout.

    Returns:
        Problem | str
    """

    return (
        await asyncio_detailed(
            client=client,
        )
    ).parsed
