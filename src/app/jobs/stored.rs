//! A job's prepared mesh as a queue shared by replicas stores it (under the job's id, with
//! [`VolumeStore::put_upload`](crate::app::store::VolumeStore::put_upload)), so that the mesh
//! is parsed once per job, by the process it was submitted to, whichever process runs it: that
//! one decodes the mesh ([`crate::mesh::binary`]) with what the submitting process found out
//! about it (its diagnostics, its source with the upload's sha256, the times they took), and
//! fits the grid again from the job's request (the spec, kept by the queue: the one place of
//! method, fill, grid options and limits) under its own limits. Not here: the request itself,
//! or where the bytes are kept.
//!
//! Layout: [`MAGIC`], a little-endian u32 version ([`VERSION`]), a little-endian u32 length
//! and that many bytes of JSON (the [`Header`]), then the mesh in its binary form. An upload
//! that does not start with [`MAGIC`] was stored by an older process as the raw mesh file; it
//! is prepared from those bytes, as then ([`is_prepared`] tells them apart).

use serde::{Deserialize, Serialize};

use super::super::error::{Error, Result};
use super::super::request::VoxelizeRequest;
use super::super::voxelize::{Loaded, Prepared, Source};
use crate::mesh::{MeshDiagnostics, binary};

/// The first bytes of a stored prepared job (a raw mesh upload never starts so: see
/// [`binary::MAGIC`] for why such a signature).
pub const MAGIC: [u8; 8] = *b"\x89VXPREP\n";

/// The layout's version; a decoder refuses one it does not know.
pub const VERSION: u32 = 1;

/// Bytes a header's JSON may take (a few hundred in practice): a length past this is corrupt.
const MAX_HEADER: usize = 64 << 10;

/// What the submitting process found out about the mesh, besides the mesh itself.
#[derive(Serialize, Deserialize)]
struct Header {
    source: String,
    format: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    compression: Option<String>,
    sha256: Option<String>,
    diagnostics: MeshDiagnostics,
    load_s: f64,
    diagnose_s: f64,
}

/// Whether an upload is a prepared job ([`encode`]'s) rather than a raw mesh file.
pub fn is_prepared(bytes: &[u8]) -> bool {
    bytes.starts_with(&MAGIC)
}

/// The prepared job `p` as a shared queue stores it. Blocking: the mesh is copied.
pub fn encode(p: &Prepared) -> Vec<u8> {
    let header = serde_json::to_vec(&Header {
        source: p.source.name.clone(),
        format: p.source.format.clone(),
        compression: p.source.compression.clone(),
        sha256: p.source.sha256.clone(),
        diagnostics: p.diagnostics.clone(),
        load_s: p.load_s,
        diagnose_s: p.diagnose_s,
    })
    .expect("a header serialises");
    let mesh = binary::encode(&p.mesh);
    let mut out = Vec::with_capacity(16 + header.len() + mesh.len());
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&(header.len() as u32).to_le_bytes());
    out.extend_from_slice(&header);
    out.extend_from_slice(&mesh);
    out
}

/// The job [`encode`] stored, prepared for `req` (the job's request over these bytes, within
/// this process's limits): the mesh decoded within the request's limits, nothing parsed or
/// diagnosed again, the grid fitted. Blocking.
pub fn decode(bytes: &[u8], req: &VoxelizeRequest) -> Result<Prepared> {
    let corrupt = |why: String| Error::internal(format!("the job's stored mesh is corrupt: {why}"));
    if bytes.len() < 16 || !is_prepared(bytes) {
        return Err(corrupt("not a prepared job".into()));
    }
    let version = u32::from_le_bytes(bytes[8..12].try_into().expect("4 bytes"));
    if version != VERSION {
        return Err(corrupt(format!(
            "version {version}, but this build reads version {VERSION} only"
        )));
    }
    let len = u32::from_le_bytes(bytes[12..16].try_into().expect("4 bytes")) as usize;
    if len > MAX_HEADER || len > bytes.len() - 16 {
        return Err(corrupt(format!(
            "a header of {len} bytes in {} bytes",
            bytes.len()
        )));
    }
    let (header, mesh) = bytes[16..].split_at(len);
    let h: Header =
        serde_json::from_slice(header).map_err(|e| corrupt(format!("its header: {e}")))?;
    let opts = req.load_options();
    // A count over this process's limits is the problem parsing the file would have given.
    let mesh = binary::decode(mesh, &opts)?;
    let d = &h.diagnostics;
    let finite = d.bbox_min.iter().chain(&d.bbox_max).all(|c| c.is_finite());
    if d.triangles != mesh.triangles().len() || !finite {
        return Err(corrupt(format!(
            "its diagnostics count {} triangles in a box {:?}–{:?}, its mesh has {}",
            d.triangles,
            d.bbox_min,
            d.bbox_max,
            mesh.triangles().len()
        )));
    }
    Loaded {
        mesh,
        diagnostics: h.diagnostics,
        source: Source {
            name: h.source,
            format: h.format,
            compression: h.compression,
            sha256: h.sha256,
        },
        load_s: h.load_s,
        diagnose_s: h.diagnose_s,
    }
    .fit(req)
}

#[cfg(test)]
mod tests {
    use bytes::Bytes;

    use super::*;
    use crate::app::request::{MeshSource, MethodSpec};
    use crate::app::testing::TETRA_OBJ as TETRA;
    use crate::engine::Method;
    use crate::engine::fill::Fill;
    use crate::grid::GridSpec;
    use crate::limits::Limits;

    fn request(bytes: Bytes, resolution: u32) -> VoxelizeRequest {
        VoxelizeRequest {
            source: MeshSource::Bytes {
                bytes,
                format: None,
            },
            grid: GridSpec::Resolution {
                n: resolution,
                cubic: false,
            },
            padding: 1,
            method: MethodSpec::Bits(Method::Solid),
            fill: Fill::Parity,
            attributes: Default::default(),
            limits: Limits::SERVICE,
        }
    }

    /// Decoding gives the prepared job back: the same mesh, diagnostics, source (the upload's
    /// sha256, not the stored bytes'), grid and times; and the stored form is no mesh file.
    #[test]
    fn a_prepared_job_round_trips() {
        let p = crate::app::prepare(&request(Bytes::from_static(TETRA), 12)).unwrap();
        let bytes = encode(&p);
        assert!(is_prepared(&bytes) && !is_prepared(TETRA));
        let stored = Bytes::from(bytes);
        assert!(crate::app::prepare(&request(stored.clone(), 12)).is_err());
        let back = decode(&stored, &request(stored.clone(), 12)).unwrap();
        assert_eq!(back.mesh, p.mesh);
        assert_eq!(back.diagnostics, p.diagnostics);
        assert_eq!(back.source, p.source);
        assert_eq!(
            back.source.sha256.as_deref(),
            Some(crate::app::sha256_hex(TETRA).as_str())
        );
        assert_eq!(back.grid, p.grid);
        assert_eq!((back.load_s, back.diagnose_s), (p.load_s, p.diagnose_s));
        // The grid is the request's: another resolution fits another one.
        let other = decode(&stored, &request(stored.clone(), 20)).unwrap();
        assert_eq!(other.grid.dims, [22, 22, 22]);
    }

    /// Truncated, corrupt or over-limit stored jobs are errors, not panics; a mesh over this
    /// process's triangle limit is refused as parsing would refuse it.
    #[test]
    fn broken_stored_jobs_are_refused() {
        let p = crate::app::prepare(&request(Bytes::from_static(TETRA), 8)).unwrap();
        let good = encode(&p);
        let req = request(Bytes::new(), 8);
        for n in 0..good.len() {
            assert!(decode(&good[..n], &req).is_err(), "prefix of {n}");
        }
        let mut b = good.clone();
        b[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(decode(&b, &req).unwrap_err().detail.contains("header of"));
        let mut b = good.clone();
        b[8] = 9;
        assert!(decode(&b, &req).unwrap_err().detail.contains("version 9"));
        let mut b = good.clone();
        b[16] = b'[';
        assert!(decode(&b, &req).unwrap_err().detail.contains("its header"));
        let mut few = request(Bytes::new(), 8);
        few.limits.max_triangles = 3;
        let e = decode(&good, &few).unwrap_err();
        assert_eq!(e.kind, crate::app::ErrorKind::TooManyTriangles, "{e:?}");
    }
}
