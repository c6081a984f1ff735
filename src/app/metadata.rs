//! The one builder of volume metadata: the keys a `.vxl` header carries (whichever front wrote
//! it) and the [`VolumeMeta`] a store keeps, both from the same facts.

use serde_json::{Map, Value};

use super::error::Result;
use super::request::{Band, MethodSpec};
use super::store::DistanceMeta;
use super::store::{MaterialMeta, SourceInfo, VolumeMeta, Vxl};
use super::voxelize::{Prepared, distance_thickness};
use crate::codec::vxl;
use crate::engine::fill::FillReport;
use crate::volume::Volume;

/// How a volume came to be.
#[derive(Clone, Copy, Debug)]
pub enum Origin<'a> {
    /// Voxelized from a mesh (by `job`, when a queue ran it).
    Mesh {
        prepared: &'a Prepared,
        fill: &'a FillReport,
        job: Option<&'a str>,
    },
    /// Computed from other volumes: `method` is `csg` or `morphology`, `provenance` says how.
    /// `materials`: the table a material channel's ids index (empty without one).
    Derived {
        method: &'a str,
        provenance: &'a Value,
        materials: &'a [super::store::MaterialMeta],
    },
}

impl Origin<'_> {
    pub fn method(&self) -> &str {
        match self {
            Origin::Mesh { prepared, .. } => prepared.method.name(),
            Origin::Derived { method, .. } => method,
        }
    }
}

/// The `.vxl` header's `meta` (docs/format.md): `method`, and for a mesh `fill`, `source` (the
/// file's name or `upload`), `source_format` (of the mesh inside a gzip'd file),
/// `source_compression` (`gzip`, when it was), `source_sha256` (uploads), `triangles`, `job`;
/// for a derived volume its `provenance`.
pub fn vxl_header(origin: &Origin) -> Map<String, Value> {
    let mut m = Map::new();
    m.insert("method".into(), origin.method().into());
    match origin {
        Origin::Mesh {
            prepared: p,
            fill,
            job,
        } => {
            m.insert("fill".into(), fill.used.name().into());
            m.insert("source".into(), p.source.name.clone().into());
            m.insert("source_format".into(), p.source.format.clone().into());
            if let Some(c) = &p.source.compression {
                m.insert("source_compression".into(), c.clone().into());
            }
            if let Some(sha) = &p.source.sha256 {
                m.insert("source_sha256".into(), sha.clone().into());
            }
            m.insert("triangles".into(), p.diagnostics.triangles.into());
            match p.method {
                MethodSpec::Sdf { band } => {
                    let (bg, _) = band.values(p.grid.voxel_size);
                    m.insert("band".into(), band_json(band));
                    m.insert(
                        "background".into(),
                        if bg.is_finite() {
                            bg.into()
                        } else {
                            "inf".into()
                        },
                    );
                }
                MethodSpec::Distance { thickness } => {
                    if let Ok(t) = distance_thickness(thickness, p.grid.voxel_size) {
                        m.insert("thickness".into(), snapped_thickness(t, &p.grid).into());
                    }
                }
                _ => {}
            }
            if let Some(job) = job {
                m.insert("job".into(), (*job).into());
            }
            if p.attributes.material {
                m.insert("materials".into(), table_json(&mesh_materials(p)));
            }
        }
        Origin::Derived {
            provenance,
            materials,
            ..
        } => {
            m.insert("provenance".into(), (*provenance).clone());
            if !materials.is_empty() {
                m.insert("materials".into(), table_json(materials));
            }
        }
    }
    m
}

fn band_json(band: Band) -> Value {
    match band {
        Band::Voxels(k) => k.into(),
        Band::All => "all".into(),
    }
}

/// A lattice thickness in world units.
fn snapped_thickness(t: i64, grid: &crate::grid::Grid) -> f64 {
    t as f64 * grid.voxel_size / crate::engine::FIXED_ONE as f64
}

/// The distance facts of `volume` made as `origin` says.
fn distance_meta(volume: &Volume, origin: &Origin) -> Option<DistanceMeta> {
    let mut d = match volume {
        Volume::SparseDistance(s) => DistanceMeta::of_sparse(s),
        _ => DistanceMeta::default(),
    };
    if let Origin::Mesh { prepared: p, .. } = origin {
        match p.method {
            MethodSpec::Sdf { band } => d.band = Some(band_json(band)),
            MethodSpec::Distance { thickness } => {
                d.thickness = distance_thickness(thickness, p.grid.voxel_size)
                    .ok()
                    .map(|t| snapped_thickness(t, &p.grid));
            }
            _ => {}
        }
    }
    (d != DistanceMeta::default()).then_some(d)
}

/// The mesh's material table (id = position).
fn mesh_materials(p: &Prepared) -> Vec<MaterialMeta> {
    p.mesh
        .attributes()
        .materials
        .iter()
        .enumerate()
        .map(|(i, m)| MaterialMeta {
            id: i as u16,
            name: m.name.clone(),
            base_color: m.base_color,
        })
        .collect()
}

/// A material table as the `.vxl` header's `meta.materials` holds it: `{name, base_color}`
/// entries, the id being the position ([`header_materials`] reads it back).
fn table_json(table: &[MaterialMeta]) -> Value {
    table
        .iter()
        .map(|mat| serde_json::json!({"name": mat.name, "base_color": mat.base_color}))
        .collect::<Vec<_>>()
        .into()
}

/// The material table a `.vxl` header's `meta.materials` holds (written by [`vxl_header`]).
pub fn header_materials(meta: &Map<String, Value>) -> Vec<MaterialMeta> {
    let Some(t) = meta.get("materials").and_then(|t| t.as_array()) else {
        return vec![];
    };
    t.iter()
        .enumerate()
        .map(|(i, m)| {
            let c: Vec<f32> = m["base_color"]
                .as_array()
                .map(|a| a.iter().map(|v| v.as_f64().unwrap_or(1.0) as f32).collect())
                .unwrap_or_default();
            MaterialMeta {
                id: i as u16,
                name: m["name"].as_str().unwrap_or("").to_string(),
                base_color: std::array::from_fn(|k| c.get(k).copied().unwrap_or(1.0)),
            }
        })
        .collect()
}

/// The channels of a channel volume, and the mesh's material table when one is a material id.
fn attributes_meta(v: &Volume, origin: &Origin) -> Option<super::store::AttributesMeta> {
    let Volume::Channels(a) = v else { return None };
    let channels: Vec<String> = a.channels().iter().map(|c| c.name.clone()).collect();
    let materials = match origin {
        Origin::Mesh { prepared: p, .. }
            if channels
                .iter()
                .any(|c| c == crate::engine::colour::MATERIAL) =>
        {
            mesh_materials(p)
        }
        Origin::Derived { materials, .. } => materials.to_vec(),
        _ => vec![],
    };
    Some(super::store::AttributesMeta {
        channels,
        materials,
    })
}

/// Set voxels (density: non-zero voxels) and occupied voxels (density: the sum of fractions).
pub fn counts(v: &Volume) -> (u64, f64) {
    match v {
        Volume::Bits(b) => {
            let n = b.count_ones();
            (n, n as f64)
        }
        Volume::Density(d) => (d.count_nonzero(), d.occupied_voxels()),
        other => (other.count_occupied(), other.count_occupied() as f64),
    }
}

/// A volume ready for a store: its metadata and its `.vxl` bytes (hashed once, for both).
pub struct Built {
    pub meta: VolumeMeta,
    pub vxl: Vxl,
    /// The source object of the mesh it keeps (`meta.source.kept`: [`super::sources`]).
    pub source: Option<bytes::Bytes>,
}

/// Encodes `volume` as `.vxl` and describes it, under a new id.
pub fn build(
    volume: &Volume,
    origin: &Origin,
    name: Option<String>,
    engine: &str,
) -> Result<Built> {
    let vxl = Vxl::new(
        vxl::encode(volume, &vxl_header(origin))
            .map_err(|e| super::Error::internal(e.to_string()))?,
    );
    let g = *volume.grid();
    let (solid, occupied) = counts(volume);
    let (source, diagnostics, fill) = match origin {
        Origin::Mesh {
            prepared: p, fill, ..
        } => (
            SourceInfo {
                format: p.source.format.clone(),
                compression: p.source.compression.clone(),
                sha256: p.source.sha256.clone().unwrap_or_default(),
                triangles: p.mesh.triangles().len(),
                kept: false,
            },
            Some(p.diagnostics.clone()),
            Some((*fill).clone()),
        ),
        Origin::Derived {
            method, provenance, ..
        } => (
            SourceInfo {
                format: (*method).into(),
                compression: None,
                sha256: super::sha256_hex(&serde_json::to_vec(provenance).unwrap_or_default()),
                triangles: 0,
                kept: false,
            },
            None,
            None,
        ),
    };
    let meta = VolumeMeta {
        id: super::new_id(),
        name,
        kind: volume.kind(),
        method: origin.method().into(),
        grid: g,
        solid_voxels: solid,
        volume: occupied * g.voxel_volume(),
        source,
        diagnostics,
        fill,
        engine: engine.into(),
        created: super::rfc3339(std::time::SystemTime::now()),
        bytes: vxl.len() as u64,
        // The bytes' one hash: the store checks against it rather than hashing them again.
        sha256: vxl.sha256().to_string(),
        provenance: match origin {
            Origin::Derived { provenance, .. } => Some((*provenance).clone()),
            Origin::Mesh { .. } => None,
        },
        distance: distance_meta(volume, origin),
        attributes: attributes_meta(volume, origin),
        // The caller sets it (a job's tenant, an operation's).
        owner: None,
    };
    Ok(Built {
        meta,
        vxl,
        source: None,
    })
}
