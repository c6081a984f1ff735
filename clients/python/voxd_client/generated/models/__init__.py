"""Contains all the data models used in inputs/outputs"""

from .bit_stats import BitStats
from .csg_expression import CsgExpression
from .csg_expression_op import CsgExpressionOp
from .distance_stats import DistanceStats
from .get_healthz_response_200 import GetHealthzResponse200
from .get_readyz_response_200 import GetReadyzResponse200
from .get_v1_viewer_file_file import GetV1ViewerFileFile
from .get_v1_volumes_id_data_attributes import GetV1VolumesIdDataAttributes
from .get_v1_volumes_id_data_format import GetV1VolumesIdDataFormat
from .get_v1_volumes_id_mesh_algorithm import GetV1VolumesIdMeshAlgorithm
from .get_v1_volumes_id_mesh_format import GetV1VolumesIdMeshFormat
from .get_v1_volumes_id_normals_response_200 import GetV1VolumesIdNormalsResponse200
from .get_v1_volumes_id_preview_png_axis import GetV1VolumesIdPreviewPngAxis
from .get_v1_volumes_id_preview_png_projection import GetV1VolumesIdPreviewPngProjection
from .get_v1_volumes_response_200 import GetV1VolumesResponse200
from .grid import Grid
from .job import Job
from .job_distance import JobDistance
from .job_distance_background_type_1 import JobDistanceBackgroundType1
from .job_distance_band_type_1 import JobDistanceBandType1
from .job_state import JobState
from .job_timings import JobTimings
from .post_v1_volumes_id_morphology_body import PostV1VolumesIdMorphologyBody
from .post_v1_volumes_id_morphology_body_kernel import (
    PostV1VolumesIdMorphologyBodyKernel,
)
from .post_v1_volumes_id_morphology_body_op import PostV1VolumesIdMorphologyBodyOp
from .post_v1_volumes_id_query_body_type_0 import PostV1VolumesIdQueryBodyType0
from .post_v1_volumes_id_query_body_type_1 import PostV1VolumesIdQueryBodyType1
from .post_v1_volumes_id_query_response_200 import PostV1VolumesIdQueryResponse200
from .post_v1_volumes_id_query_response_200_points_item import (
    PostV1VolumesIdQueryResponse200PointsItem,
)
from .post_v1_volumes_id_query_response_200_rays_item import (
    PostV1VolumesIdQueryResponse200RaysItem,
)
from .post_v1_volumes_intersect_body import PostV1VolumesIntersectBody
from .post_v1_volumes_intersect_response_200 import PostV1VolumesIntersectResponse200
from .post_v1_voxelize_band_type_1 import PostV1VoxelizeBandType1
from .post_v1_voxelize_content_encoding import PostV1VoxelizeContentEncoding
from .post_v1_voxelize_density_factor import PostV1VoxelizeDensityFactor
from .post_v1_voxelize_fill import PostV1VoxelizeFill
from .post_v1_voxelize_format import PostV1VoxelizeFormat
from .post_v1_voxelize_method import PostV1VoxelizeMethod
from .problem import Problem
from .volume import Volume
from .volume_attributes import VolumeAttributes
from .volume_attributes_channels_item import VolumeAttributesChannelsItem
from .volume_attributes_materials_item import VolumeAttributesMaterialsItem
from .volume_diagnostics_type_0 import VolumeDiagnosticsType0
from .volume_distance import VolumeDistance
from .volume_distance_background_type_1 import VolumeDistanceBackgroundType1
from .volume_distance_band_type_1 import VolumeDistanceBandType1
from .volume_fill import VolumeFill
from .volume_fill_requested import VolumeFillRequested
from .volume_fill_used import VolumeFillUsed
from .volume_fill_winding import VolumeFillWinding
from .volume_kind import VolumeKind
from .volume_source import VolumeSource
from .volume_source_compression import VolumeSourceCompression

__all__ = (
    "BitStats",
    "CsgExpression",
    "CsgExpressionOp",
    "DistanceStats",
    "GetHealthzResponse200",
    "GetReadyzResponse200",
    "GetV1ViewerFileFile",
    "GetV1VolumesIdDataAttributes",
    "GetV1VolumesIdDataFormat",
    "GetV1VolumesIdMeshAlgorithm",
    "GetV1VolumesIdMeshFormat",
    "GetV1VolumesIdNormalsResponse200",
    "GetV1VolumesIdPreviewPngAxis",
    "GetV1VolumesIdPreviewPngProjection",
    "GetV1VolumesResponse200",
    "Grid",
    "Job",
    "JobDistance",
    "JobDistanceBackgroundType1",
    "JobDistanceBandType1",
    "JobState",
    "JobTimings",
    "PostV1VolumesIdMorphologyBody",
    "PostV1VolumesIdMorphologyBodyKernel",
    "PostV1VolumesIdMorphologyBodyOp",
    "PostV1VolumesIdQueryBodyType0",
    "PostV1VolumesIdQueryBodyType1",
    "PostV1VolumesIdQueryResponse200",
    "PostV1VolumesIdQueryResponse200PointsItem",
    "PostV1VolumesIdQueryResponse200RaysItem",
    "PostV1VolumesIntersectBody",
    "PostV1VolumesIntersectResponse200",
    "PostV1VoxelizeBandType1",
    "PostV1VoxelizeContentEncoding",
    "PostV1VoxelizeDensityFactor",
    "PostV1VoxelizeFill",
    "PostV1VoxelizeFormat",
    "PostV1VoxelizeMethod",
    "Problem",
    "Volume",
    "VolumeAttributes",
    "VolumeAttributesChannelsItem",
    "VolumeAttributesMaterialsItem",
    "VolumeDiagnosticsType0",
    "VolumeDistance",
    "VolumeDistanceBackgroundType1",
    "VolumeDistanceBandType1",
    "VolumeFill",
    "VolumeFillRequested",
    "VolumeFillUsed",
    "VolumeFillWinding",
    "VolumeKind",
    "VolumeSource",
    "VolumeSourceCompression",
)
