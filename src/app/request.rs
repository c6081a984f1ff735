//! Typed requests: what a front (the command line, an HTTP handler, a queue consumer) hands the
//! application once it has translated its own input. Each request is checked here, against
//! [`Limits`], before any work starts.

use std::path::PathBuf;

use bytes::Bytes;
use serde::{Deserialize, Serialize};

use super::error::{Error, Result};
use crate::engine::Method;
pub use crate::engine::colour::Want;
use crate::engine::fill::Fill;
pub use crate::engine::sdf::Band;
use crate::grid::GridSpec;
use crate::limits::Limits;
use crate::mesh::{ExternalResources, Format, LoadOptions};
use crate::names::Named;
use crate::volume::csg::CsgOp;
use crate::volume::morph::{Kernel, MorphOp};

/// A bit method, density with its sub-voxel factor (2 or 4), distance with its thickness
/// (world units; `None`: half the voxel diagonal), or sdf with its band.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MethodSpec {
    Bits(Method),
    Density { factor: u32 },
    Distance { thickness: Option<f64> },
    Sdf { band: Band },
}

/// The parameters a method may take beside its name, each valid with one method only.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MethodParams {
    pub density_factor: Option<u32>,
    pub thickness: Option<f64>,
    pub band: Option<Band>,
}

impl MethodSpec {
    pub const DEFAULT_DENSITY_FACTOR: u32 = 2;

    /// The method named `name`, with `density_factor` for density (2 when not given); a
    /// `density_factor` given with another method is refused (it applies only to density).
    pub fn new(name: &str, density_factor: Option<u32>) -> Result<MethodSpec> {
        MethodSpec::with(
            name,
            MethodParams {
                density_factor,
                ..MethodParams::default()
            },
        )
    }

    /// The method named `name` with its parameters: `density_factor` only with density,
    /// `thickness` only with distance (finite, ≥ 0), `band` only with sdf (3 when not given).
    pub fn with(name: &str, params: MethodParams) -> Result<MethodSpec> {
        let method = crate::names::parse::<MethodName>(name).map_err(Error::invalid)?;
        let misplaced = |param: String, only: &str| {
            Error::invalid(format!(
                "{param} is given with method={}: {} applies only to method={only}",
                method.name(),
                param.split('=').next().unwrap_or_default()
            ))
        };
        if let (Some(f), false) = (params.density_factor, method == MethodName::Density) {
            return Err(misplaced(format!("density_factor={f}"), "density"));
        }
        if let (Some(t), false) = (params.thickness, method == MethodName::Distance) {
            return Err(misplaced(format!("thickness={t}"), "distance"));
        }
        if let (Some(b), false) = (params.band, method == MethodName::Sdf) {
            return Err(misplaced(format!("band={b}"), "sdf"));
        }
        let density_factor = params.density_factor;
        match method {
            MethodName::Bits(m) => Ok(MethodSpec::Bits(m)),
            MethodName::Distance => match params.thickness {
                Some(t) if !(t.is_finite() && t >= 0.0) => Err(Error::invalid(format!(
                    "thickness must be a finite number ≥ 0 (world units), got {t}"
                ))),
                thickness => Ok(MethodSpec::Distance { thickness }),
            },
            MethodName::Sdf => Ok(MethodSpec::Sdf {
                band: params.band.unwrap_or(Band::DEFAULT),
            }),
            MethodName::Density => {
                match density_factor.unwrap_or(MethodSpec::DEFAULT_DENSITY_FACTOR) {
                    f @ (2 | 4) => Ok(MethodSpec::Density { factor: f }),
                    f => Err(Error::invalid(format!(
                        "density_factor must be 2 or 4, got {f}"
                    ))),
                }
            }
        }
    }

    /// The fill for this method: `fill`, else [`Fill::DEFAULT`]. `surface` has no inside, so a
    /// fill given with it is refused.
    pub fn fill(self, fill: Option<Fill>) -> Result<Fill> {
        match (self, fill) {
            (MethodSpec::Bits(Method::Surface) | MethodSpec::Distance { .. }, Some(f)) => {
                Err(Error::invalid(format!(
                    "fill={f} is given with method={}, which has no inside: fill applies only to method=solid, conservative, interior, density or sdf",
                    self.name()
                )))
            }
            (_, f) => Ok(f.unwrap_or(Fill::DEFAULT)),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            MethodSpec::Bits(m) => m.name(),
            MethodSpec::Density { .. } => MethodName::Density.name(),
            MethodSpec::Distance { .. } => MethodName::Distance.name(),
            MethodSpec::Sdf { .. } => MethodName::Sdf.name(),
        }
    }

    /// `want` checked against this method: colour and material channels go with the bit
    /// methods and distance only (density and sdf volumes are not bits).
    pub fn attributes(self, want: Want) -> Result<Want> {
        match self {
            MethodSpec::Bits(_) | MethodSpec::Distance { .. } => Ok(want),
            _ if !want.any() => Ok(want),
            _ => Err(Error::invalid(format!(
                "{} is given with method={}: color and material apply only to method=solid, surface, conservative, interior or distance",
                if want.colour {
                    "color=true"
                } else {
                    "material=true"
                },
                self.name()
            ))),
        }
    }

    /// Voxels the engine classifies per voxel of the grid.
    pub fn voxels_per_voxel(self) -> u64 {
        match self {
            MethodSpec::Bits(_) | MethodSpec::Distance { .. } | MethodSpec::Sdf { .. } => 1,
            MethodSpec::Density { factor } => u64::from(factor).pow(3),
        }
    }
}

/// The names a user may give as a method: the bit methods ([`Method`]'s table), `density`,
/// `distance` and `sdf`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MethodName {
    Bits(Method),
    Density,
    Distance,
    Sdf,
}

impl MethodName {
    /// The method when none is named (the command line's `--method` and the service's).
    pub const DEFAULT: MethodName = MethodName::Bits(Method::Solid);
}

impl Named for MethodName {
    const WHAT: &'static str = "method";
    /// [`Method::ALL`], then `density`, `distance` and `sdf`: a bit method added there is a
    /// name here.
    const ALL: &'static [MethodName] = &{
        let n = Method::ALL.len();
        let mut all = [MethodName::Density; Method::ALL.len() + 3];
        let mut i = 0;
        while i < n {
            all[i] = MethodName::Bits(Method::ALL[i]);
            i += 1;
        }
        all[n + 1] = MethodName::Distance;
        all[n + 2] = MethodName::Sdf;
        all
    };
    fn name(self) -> &'static str {
        match self {
            MethodName::Bits(m) => m.name(),
            MethodName::Density => "density",
            MethodName::Distance => "distance",
            MethodName::Sdf => "sdf",
        }
    }
}

crate::impl_named!(MethodName);

/// Where a mesh comes from.
#[derive(Clone, Debug)]
pub enum MeshSource {
    /// A file; its format from `format`, else its extension, else its content. A `.gltf` may
    /// read buffers beside it.
    File {
        path: PathBuf,
        format: Option<Format>,
    },
    /// Uploaded bytes (gzip'd or not); external glTF resources are refused.
    Bytes {
        bytes: Bytes,
        format: Option<Format>,
    },
}

impl MeshSource {
    /// The name a volume records as its source: the file's name, or `upload`.
    pub fn display_name(&self) -> String {
        match self {
            MeshSource::File { path, .. } => path
                .file_name()
                .map(|f| f.to_string_lossy().into_owned())
                .unwrap_or_default(),
            MeshSource::Bytes { .. } => "upload".into(),
        }
    }

    pub(crate) fn external(&self) -> ExternalResources {
        match self {
            MeshSource::File { path, .. } => {
                ExternalResources::BesideFile(path.parent().map(PathBuf::from).unwrap_or_default())
            }
            MeshSource::Bytes { .. } => ExternalResources::Deny,
        }
    }
}

/// Everything a voxelization needs.
#[derive(Clone, Debug)]
pub struct VoxelizeRequest {
    pub source: MeshSource,
    pub grid: GridSpec,
    /// Empty voxels added on every side.
    pub padding: u32,
    pub method: MethodSpec,
    pub fill: Fill,
    /// The attribute channels asked for (`color`, `material`), checked against the method
    /// ([`MethodSpec::attributes`]).
    pub attributes: Want,
    pub limits: Limits,
}

impl VoxelizeRequest {
    /// How its mesh is parsed, within its limits, and its parse's memory estimated
    /// (`mesh::cost::estimate`): the one set of options both use, so the estimate holds for the
    /// parse. Textures are read only for colour.
    pub fn load_options(&self) -> LoadOptions {
        LoadOptions {
            external: self.source.external(),
            max_triangles: self.limits.max_triangles,
            max_decompressed_bytes: self.limits.max_decompressed_bytes,
            max_texture_bytes: self.limits.max_texture_bytes,
            textures: self.attributes.colour,
        }
    }
}

/// An uploaded voxelization request as data, without the upload's bytes: what a queue shared by
/// replicas keeps with a job, so that whichever process runs it rebuilds the same request from
/// the stored upload ([`JobSpec::request`]) and prepares it to the same bits.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JobSpec {
    /// The declared mesh format (`None`: sniffed).
    pub format: Option<String>,
    pub grid: GridSpec,
    pub padding: u32,
    /// A method name (`solid`, …, `density`).
    pub method: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub density_factor: Option<u32>,
    /// distance's thickness (world units), when given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thickness: Option<f64>,
    /// sdf's band: `3`, …, or `all`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub band: Option<String>,
    pub fill: Fill,
    /// `color=true`, `material=true`.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub color: bool,
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub material: bool,
    /// The limits loading, fitting and running are held to (a request may lower the server's).
    pub max_voxels: u64,
    pub max_triangles: usize,
    pub max_decompressed_bytes: u64,
}

impl JobSpec {
    /// The request as data (its source's bytes or path left out).
    pub fn of(req: &VoxelizeRequest) -> JobSpec {
        let (MeshSource::File { format, .. } | MeshSource::Bytes { format, .. }) = &req.source;
        JobSpec {
            format: format.map(|f| f.name().to_string()),
            grid: req.grid,
            padding: req.padding,
            method: req.method.name().into(),
            density_factor: match req.method {
                MethodSpec::Density { factor } => Some(factor),
                _ => None,
            },
            thickness: match req.method {
                MethodSpec::Distance { thickness } => thickness,
                _ => None,
            },
            band: match req.method {
                MethodSpec::Sdf { band } => Some(band.to_string()),
                _ => None,
            },
            fill: req.fill,
            color: req.attributes.colour,
            material: req.attributes.material,
            max_voxels: req.limits.max_voxels,
            max_triangles: req.limits.max_triangles,
            max_decompressed_bytes: req.limits.max_decompressed_bytes,
        }
    }

    /// The request again, over the upload's `bytes`, within `server`'s limits (those of the
    /// process that runs it: what a shared queue hands over cannot raise them).
    pub fn request(&self, bytes: Bytes, server: &Limits) -> Result<VoxelizeRequest> {
        let format = match &self.format {
            None => None,
            Some(f) => Some(
                Format::from_name(f)
                    .ok_or_else(|| Error::invalid(format!("unknown mesh format {f:?}")))?,
            ),
        };
        let method = MethodSpec::with(
            &self.method,
            MethodParams {
                density_factor: self.density_factor,
                thickness: self.thickness,
                band: match &self.band {
                    Some(b) => Some(Band::parse(b).map_err(Error::invalid)?),
                    None => None,
                },
            },
        )?;
        Ok(VoxelizeRequest {
            source: MeshSource::Bytes { bytes, format },
            grid: self.grid,
            padding: self.padding,
            method,
            fill: self.fill,
            attributes: method.attributes(Want {
                colour: self.color,
                material: self.material,
            })?,
            limits: Limits {
                max_voxels: self.max_voxels.min(server.max_voxels),
                max_triangles: self.max_triangles.min(server.max_triangles),
                max_decompressed_bytes: self
                    .max_decompressed_bytes
                    .min(server.max_decompressed_bytes),
                ..*server
            },
        })
    }
}

/// How the grid was asked for, as the fronts receive it: every option optional.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GridOptions {
    pub resolution: Option<u32>,
    pub voxel_size: Option<f64>,
    pub origin: Option<[f64; 3]>,
    pub dims: Option<[u32; 3]>,
    pub cubic: bool,
}

impl GridOptions {
    /// The one precedence of grid options: an explicit grid needs origin, dims and voxel size
    /// together (and no resolution); otherwise a voxel size or a resolution (not both), with
    /// `default_resolution` when neither is given.
    pub fn spec(&self, default_resolution: u32) -> Result<GridSpec> {
        match (self.origin, self.dims, self.voxel_size, self.resolution) {
            (Some(origin), Some(dims), Some(voxel_size), None) => Ok(GridSpec::Explicit {
                origin,
                voxel_size,
                dims,
            }),
            (Some(_), _, _, _) | (_, Some(_), _, _) => Err(Error::invalid(
                "an explicit grid needs origin, dims and voxel_size together (and no resolution)",
            )),
            (None, None, Some(size), None) => Ok(GridSpec::VoxelSize {
                size,
                cubic: self.cubic,
            }),
            (None, None, None, r) => Ok(GridSpec::Resolution {
                n: r.unwrap_or(default_resolution),
                cubic: self.cubic,
            }),
            (None, None, Some(_), Some(_)) => {
                Err(Error::invalid("give resolution or voxel_size, not both"))
            }
        }
    }
}

/// A boolean expression over stored volumes: a volume id, or an operation over operands.
/// In JSON: `"<id>"` or `{"op": "union", "operands": [...]}`.
#[derive(Clone, Debug, PartialEq)]
pub enum CsgExpr {
    Volume(String),
    Op { op: CsgOp, operands: Vec<CsgExpr> },
}

impl CsgExpr {
    /// Parses and checks an expression against the depth, operand and size limits (the
    /// expression is kept as the result's provenance, so its size is bounded too).
    pub fn from_json(v: &serde_json::Value, limits: &Limits) -> Result<CsgExpr> {
        let e = Self::parse(v, 0, limits)?;
        let size = e.to_json().to_string().len();
        if size > limits.max_provenance_bytes {
            return Err(Error::invalid(format!(
                "the expression takes {size} bytes as JSON, over the limit of {}",
                limits.max_provenance_bytes
            )));
        }
        Ok(e)
    }

    fn parse(v: &serde_json::Value, depth: usize, limits: &Limits) -> Result<CsgExpr> {
        use serde_json::Value;
        if depth > limits.max_csg_depth {
            return Err(Error::invalid(format!(
                "the expression is nested deeper than {}",
                limits.max_csg_depth
            )));
        }
        match v {
            Value::String(id) => Ok(CsgExpr::Volume(id.clone())),
            Value::Object(o) => {
                if let Some(k) = o.keys().find(|k| *k != "op" && *k != "operands") {
                    return Err(Error::invalid(format!(
                        "unknown field {k:?} in an expression node; a node has \"op\" and \"operands\""
                    )));
                }
                let op = o
                    .get("op")
                    .and_then(Value::as_str)
                    .ok_or_else(|| Error::invalid("every expression node needs \"op\""))?;
                let op = crate::names::parse::<CsgOp>(op).map_err(Error::invalid)?;
                let operands = o.get("operands").and_then(Value::as_array).ok_or_else(|| {
                    Error::invalid("every expression node needs an \"operands\" array")
                })?;
                if operands.is_empty() || operands.len() > limits.max_csg_operands {
                    return Err(Error::invalid(format!(
                        "an operation takes 1 to {} operands",
                        limits.max_csg_operands
                    )));
                }
                let operands = operands
                    .iter()
                    .map(|x| Self::parse(x, depth + 1, limits))
                    .collect::<Result<_>>()?;
                Ok(CsgExpr::Op { op, operands })
            }
            other => Err(Error::invalid(format!(
                "an operand is a volume id (string) or an {{\"op\", \"operands\"}} object, not {other}"
            ))),
        }
    }

    /// The expression as JSON (what a derived volume keeps as its provenance).
    pub fn to_json(&self) -> serde_json::Value {
        match self {
            CsgExpr::Volume(id) => id.clone().into(),
            CsgExpr::Op { op, operands } => serde_json::json!({
                "op": op.name(),
                "operands": operands.iter().map(CsgExpr::to_json).collect::<Vec<_>>(),
            }),
        }
    }

    /// Every volume id the expression names, each once, in first-use order.
    pub fn volume_ids(&self) -> Vec<String> {
        fn walk(e: &CsgExpr, out: &mut Vec<String>) {
            match e {
                CsgExpr::Volume(id) => {
                    if !out.contains(id) {
                        out.push(id.clone())
                    }
                }
                CsgExpr::Op { operands, .. } => operands.iter().for_each(|o| walk(o, out)),
            }
        }
        let mut out = vec![];
        walk(self, &mut out);
        out
    }
}

/// A morphology operation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MorphologyRequest {
    pub op: MorphOp,
    #[serde(default = "default_kernel")]
    pub kernel: Kernel,
    pub radius: u32,
    /// Enlarge the grid by the radius (dilate and close), so nothing is clipped.
    #[serde(default)]
    pub grow: bool,
}

fn default_kernel() -> Kernel {
    Kernel::Cube
}

impl MorphologyRequest {
    pub fn check(&self, limits: &Limits) -> Result<()> {
        if self.radius > limits.max_morph_radius {
            return Err(Error::invalid(format!(
                "radius {} is over the limit of {}",
                self.radius, limits.max_morph_radius
            )));
        }
        Ok(())
    }
}

/// Points and rays to look up in a volume (world coordinates).
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct QueryRequest {
    #[serde(default)]
    pub points: Vec<[f64; 3]>,
    #[serde(default)]
    pub rays: Vec<Ray>,
}

#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Ray {
    pub origin: [f64; 3],
    pub direction: [f64; 3],
}

impl QueryRequest {
    pub fn check(&self, limits: &Limits) -> Result<()> {
        if self.points.is_empty() && self.rays.is_empty() {
            return Err(Error::invalid(
                "give \"points\": [[x, y, z], ...] or \"rays\": [{\"origin\": ..., \"direction\": ...}, ...]",
            ));
        }
        if self.points.len() + self.rays.len() > limits.max_queries {
            return Err(Error::invalid(format!(
                "at most {} points and rays per request",
                limits.max_queries
            )));
        }
        let finite = |p: &[f64; 3]| p.iter().all(|c| c.is_finite());
        if !self.points.iter().all(finite) {
            return Err(Error::invalid("a point must hold three finite numbers"));
        }
        if !self
            .rays
            .iter()
            .all(|r| finite(&r.origin) && finite(&r.direction))
        {
            return Err(Error::invalid(
                "a ray's origin and direction must hold three finite numbers",
            ));
        }
        Ok(())
    }
}

/// A preview picture: one slice, or a projection along an axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PreviewRequest {
    /// 0, 1, 2 for x, y, z.
    pub axis: usize,
    pub view: PreviewView,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PreviewView {
    Slice(u32),
    Projection(crate::volume::preview::Projection),
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The method names are the bit methods' then `density`, in the order (and with the
    /// message) the hand-written list gave.
    #[test]
    fn method_names_are_the_bit_methods_and_density() {
        let names: Vec<&str> = MethodName::ALL.iter().map(|m| m.name()).collect();
        assert_eq!(
            names,
            [
                "solid",
                "surface",
                "conservative",
                "interior",
                "density",
                "distance",
                "sdf"
            ]
        );
        assert_eq!(
            MethodSpec::new("voxel", None).unwrap_err().detail,
            "unknown method \"voxel\"; expected solid, surface, conservative, interior, density, distance or sdf"
        );
        assert_eq!(
            MethodSpec::new("density", None).unwrap(),
            MethodSpec::Density { factor: 2 }
        );
        assert_eq!(MethodSpec::Density { factor: 4 }.name(), "density");
        // density_factor only with density; fill not with surface; auto by default.
        let e = MethodSpec::new("solid", Some(2)).unwrap_err();
        assert!(
            e.detail
                .contains("density_factor=2 is given with method=solid")
        );
        let surface = MethodSpec::new("surface", None).unwrap();
        assert!(surface.fill(Some(Fill::Winding)).is_err());
        assert_eq!(surface.fill(None).unwrap(), Fill::Auto);
        let solid = MethodSpec::new("solid", None).unwrap();
        assert_eq!(solid.fill(None).unwrap(), Fill::Auto);
        assert_eq!(solid.fill(Some(Fill::Parity)).unwrap(), Fill::Parity);
        assert_eq!(MethodName::DEFAULT.to_string(), "solid");
    }

    /// thickness only with distance, band only with sdf; each checked; both round trip
    /// through a job spec.
    #[test]
    fn distance_and_sdf_take_their_own_parameters() {
        let p = |density_factor, thickness, band| MethodParams {
            density_factor,
            thickness,
            band,
        };
        assert_eq!(
            MethodSpec::with("sdf", p(None, None, None)).unwrap(),
            MethodSpec::Sdf {
                band: Band::Voxels(3)
            }
        );
        assert_eq!(
            MethodSpec::with("sdf", p(None, None, Some(Band::All))).unwrap(),
            MethodSpec::Sdf { band: Band::All }
        );
        assert_eq!(
            MethodSpec::with("distance", p(None, Some(0.25), None)).unwrap(),
            MethodSpec::Distance {
                thickness: Some(0.25)
            }
        );
        let e = MethodSpec::with("solid", p(None, None, Some(Band::Voxels(2)))).unwrap_err();
        assert!(
            e.detail
                .contains("band=2 is given with method=solid: band applies only to method=sdf"),
            "{}",
            e.detail
        );
        let e = MethodSpec::with("sdf", p(None, Some(1.0), None)).unwrap_err();
        assert!(
            e.detail
                .contains("thickness applies only to method=distance"),
            "{}",
            e.detail
        );
        assert!(MethodSpec::with("sdf", p(Some(2), None, None)).is_err());
        for bad in [-1.0, f64::NAN, f64::INFINITY] {
            assert!(MethodSpec::with("distance", p(None, Some(bad), None)).is_err());
        }
        let distance = MethodSpec::with("distance", p(None, None, None)).unwrap();
        assert!(distance.fill(Some(Fill::Winding)).is_err());
        let sdf = MethodSpec::Sdf { band: Band::All };
        assert_eq!(sdf.fill(Some(Fill::Winding)).unwrap(), Fill::Winding);
        let bytes = Bytes::from_static(crate::app::testing::TETRA_OBJ);
        for method in [
            sdf,
            MethodSpec::Sdf {
                band: Band::Voxels(7),
            },
            distance,
            MethodSpec::Distance {
                thickness: Some(0.5),
            },
        ] {
            let req = VoxelizeRequest {
                source: MeshSource::Bytes {
                    bytes: bytes.clone(),
                    format: Some(Format::Obj),
                },
                grid: GridSpec::Resolution {
                    n: 16,
                    cubic: false,
                },
                padding: 1,
                method,
                fill: Fill::Winding,
                attributes: Default::default(),
                limits: Limits::SERVICE,
            };
            let json = serde_json::to_string(&JobSpec::of(&req)).unwrap();
            let back: JobSpec = serde_json::from_str(&json).unwrap();
            assert_eq!(
                back.request(bytes.clone(), &Limits::SERVICE)
                    .unwrap()
                    .method,
                method,
                "{json}"
            );
        }
    }

    /// A request kept as a job spec (JSON, as a shared queue stores it) comes back as the same
    /// request and prepares to the same grid; the running process's limits cap the spec's.
    #[test]
    fn a_job_spec_round_trips_and_cannot_raise_the_limits() {
        let bytes = Bytes::from_static(crate::app::testing::TETRA_OBJ);
        let req = VoxelizeRequest {
            source: MeshSource::Bytes {
                bytes: bytes.clone(),
                format: Some(Format::Obj),
            },
            grid: GridSpec::Explicit {
                origin: [-0.1, -0.2, 0.1 + 0.2],
                voxel_size: 0.1 / 3.0,
                dims: [40, 41, 42],
            },
            padding: 2,
            method: MethodSpec::Density { factor: 4 },
            fill: Fill::Winding,
            attributes: Default::default(),
            limits: Limits {
                max_voxels: 1 << 30,
                ..Limits::SERVICE
            },
        };
        let spec = JobSpec::of(&req);
        let json = serde_json::to_string(&spec).unwrap();
        let back: JobSpec = serde_json::from_str(&json).unwrap();
        assert_eq!(back, spec);
        let again = back.request(bytes.clone(), &Limits::SERVICE).unwrap();
        assert_eq!(
            (again.grid, again.padding, again.method, again.fill),
            (req.grid, req.padding, req.method, req.fill)
        );
        assert_eq!(again.limits, req.limits);
        let (a, b) = (
            crate::app::prepare(&req).unwrap(),
            crate::app::prepare(&again).unwrap(),
        );
        assert_eq!((a.grid, a.source), (b.grid, b.source));
        let small = Limits {
            max_voxels: 1000,
            ..Limits::SERVICE
        };
        assert_eq!(back.request(bytes, &small).unwrap().limits.max_voxels, 1000);
        let mut bad = spec;
        bad.format = Some("doc".into());
        assert!(bad.request(Bytes::new(), &Limits::SERVICE).is_err());
    }
}
