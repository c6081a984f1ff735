//! CSG and morphology of volumes with attribute channels (colour, material ids), by the rules of
//! [`crate::engine::colour::carry`]: the first operand set at a voxel gives its values, added
//! voxels take their nearest source voxel's. Material ids are mapped onto one merged table first
//! ([`merge_materials`]). The bit-only paths stay in `ops.rs`; these are taken when an operand
//! has channels.

use std::collections::HashMap;
use std::sync::Arc;

use super::error::{Error, Result};
use super::metadata::Origin;
use super::ops::{Label, blocking_with, eval_tree, load, morphology_provenance, morphology_with};
use super::request::{CsgExpr, MorphologyRequest};
use super::store::{AttributesMeta, MaterialMeta, VolumeMeta, VolumeStore};
use crate::cancel::Control;
use crate::engine::colour::carry::{self, CarryError};
use crate::engine::colour::{MATERIAL, RGBA};
use crate::limits::Limits;
use crate::volume::kind::VoxelValue;
use crate::volume::{Attributed, Volume};

impl From<CarryError> for Error {
    fn from(e: CarryError) -> Self {
        match e {
            CarryError::Csg(e) => e.into(),
            CarryError::Canceled(c) => c.into(),
            CarryError::ChannelTypes(_) => Error::invalid(e.to_string()),
        }
    }
}

/// The name of the material table's entry for voxels no operand with a material channel covers.
pub const NO_MATERIAL: &str = "none";

/// One material table for operands with attributes `metas` (in the expression's order): each operand's
/// materials in order, an entry equal (name and base colour) to one already there reused; a
/// "none" entry (base colour (0, 0, 0, 0)) at the end when an operand has no material channel
/// while another has. Returns the table, each operand's id map, and the "none" id.
pub fn merge_materials(
    metas: &[Option<&AttributesMeta>],
) -> (Vec<MaterialMeta>, Vec<Vec<u16>>, Option<u16>) {
    let has =
        |m: &Option<&AttributesMeta>| m.is_some_and(|a| a.channels.iter().any(|c| c == MATERIAL));
    let mut table: Vec<MaterialMeta> = vec![];
    let mut maps = vec![];
    for m in metas {
        let mut map = vec![];
        if has(m) {
            for mat in &m.expect("has").materials {
                let id = match table
                    .iter()
                    .position(|t| t.name == mat.name && t.base_color == mat.base_color)
                {
                    Some(i) => i,
                    None => {
                        table.push(MaterialMeta {
                            id: table.len() as u16,
                            name: mat.name.clone(),
                            base_color: mat.base_color,
                        });
                        table.len() - 1
                    }
                };
                // Ids index the table by position (`id` = position).
                let at = usize::from(mat.id);
                if map.len() <= at {
                    map.resize(at + 1, 0);
                }
                map[at] = id as u16;
            }
        }
        maps.push(map);
    }
    let none = (metas.iter().any(has) && metas.iter().any(|m| !has(m))).then(|| {
        table.push(MaterialMeta {
            id: table.len() as u16,
            name: NO_MATERIAL.into(),
            base_color: [0.0; 4],
        });
        table.len() as u16 - 1
    });
    (table, maps, none)
}

/// A loaded operand as an attributed volume (a bit volume: no channels). Callers have checked
/// its kind against `csg::ACCEPTS`.
fn attributed(v: Volume, id: &str) -> Result<Attributed> {
    match v {
        Volume::Channels(a) => Ok(a),
        other => other
            .into_bits("CSG")
            .map(Attributed::new)
            .map_err(|e| Error::from(e).context(format!("volume {id}"))),
    }
}

/// A CSG expression over stored volumes of which some have channels, stored.
/// `metas`: the operands' metadata, in the order of `expr.volume_ids()`.
pub async fn csg_stored_with(
    store: &dyn VolumeStore,
    expr: CsgExpr,
    metas: Vec<VolumeMeta>,
    label: Label,
    ctl: &Control,
) -> Result<VolumeMeta> {
    let ids = expr.volume_ids();
    let mut operands = vec![];
    for (id, m) in ids.iter().zip(metas) {
        operands.push((id.clone(), load(store, id).await?, m.attributes));
    }
    let provenance = expr.to_json();
    let (v, table) = blocking_with(ctl, move |ctl| combine(&expr, operands, ctl)).await?;
    ctl.check()?;
    store_attributed(store, v, label, "csg", provenance, table).await
}

/// A CSG expression over `operands` (each id with its volume, bits or channels, and its
/// attributes' metadata), with channels carried: the result and its material table.
pub fn combine(
    expr: &CsgExpr,
    operands: Vec<(String, Volume, Option<AttributesMeta>)>,
    ctl: &Control,
) -> Result<(Attributed, Vec<MaterialMeta>)> {
    let attrs: Vec<Option<&AttributesMeta>> = operands.iter().map(|o| o.2.as_ref()).collect();
    let (table, maps, none) = merge_materials(&attrs);
    let mut vols: HashMap<String, Arc<Attributed>> = HashMap::new();
    for (k, (id, v, _)) in operands.into_iter().enumerate() {
        let a = attributed(v, &id)?;
        let a = if maps[k].is_empty() {
            a
        } else {
            carry::remap(&a, MATERIAL, &maps[k])
        };
        vols.insert(id, Arc::new(a));
    }
    let missing = move |name: &str| match name {
        MATERIAL => none.map(VoxelValue::U16),
        RGBA => Some(VoxelValue::Rgba8([0; 4])),
        _ => None,
    };
    let v = eval_tree(expr, &vols, ctl, |op, refs, part| {
        Ok(carry::csg(op, refs, &missing, part)?)
    })?;
    Ok((v, table))
}

/// Morphology of a stored volume with channels, stored with its material table.
pub async fn morphology_stored_with(
    store: &dyn VolumeStore,
    meta: VolumeMeta,
    req: MorphologyRequest,
    label: Label,
    limits: Limits,
    ctl: &Control,
) -> Result<VolumeMeta> {
    let id = meta.id.clone();
    let Volume::Channels(src) = load(store, &id).await? else {
        return Err(Error::internal(
            "the volume's kind changed while it was read",
        ));
    };
    let table = meta.attributes.map(|a| a.materials).unwrap_or_default();
    let out = blocking_with(ctl, move |ctl| morphology(&src, &req, &limits, ctl)).await?;
    ctl.check()?;
    store_attributed(
        store,
        out,
        label,
        "morphology",
        morphology_provenance(&id, &req),
        table,
    )
    .await
}

/// Morphology of a volume with channels within the limits, its channels carried.
pub fn morphology(
    src: &Attributed,
    req: &MorphologyRequest,
    limits: &Limits,
    ctl: &Control,
) -> Result<Attributed> {
    let bits = morphology_with(src.bits(), req, limits, &ctl.stage(0.0, 0.6))?;
    Ok(carry::morphology(src, bits, &ctl.stage(0.6, 1.0))?)
}

/// Stores a derived volume with channels and its material table.
async fn store_attributed(
    store: &dyn VolumeStore,
    v: Attributed,
    label: Label,
    method: &'static str,
    provenance: serde_json::Value,
    materials: Vec<MaterialMeta>,
) -> Result<VolumeMeta> {
    let Label { name, owner } = label;
    let mut built = super::ops::blocking(move || {
        super::metadata::build(
            &Volume::Channels(v),
            &Origin::Derived {
                method,
                provenance: &provenance,
                materials: &materials,
            },
            name,
            super::ops::DERIVED_ENGINE,
        )
    })
    .await?;
    built.meta.owner = owner;
    store.put(built.meta.clone(), built.vxl).await?;
    Ok(built.meta)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn attrs(channels: &[&str], materials: &[(&str, f32)]) -> AttributesMeta {
        AttributesMeta {
            channels: channels.iter().map(|c| c.to_string()).collect(),
            materials: materials
                .iter()
                .enumerate()
                .map(|(i, (n, c))| MaterialMeta {
                    id: i as u16,
                    name: n.to_string(),
                    base_color: [*c; 4],
                })
                .collect(),
        }
    }

    /// Equal entries (name and colour) are shared, others appended in operand order; a "none"
    /// entry only when some operand has no material channel and another has.
    #[test]
    fn material_tables_merge_in_operand_order() {
        let a = attrs(&["rgba", "material"], &[("red", 1.0), ("wood", 0.5)]);
        let b = attrs(
            &["material"],
            &[("wood", 0.5), ("red", 0.9), ("steel", 0.2)],
        );
        let colour_only = attrs(&["rgba"], &[]);
        let (table, maps, none) = merge_materials(&[Some(&a), Some(&b)]);
        let names: Vec<(&str, f32)> = table
            .iter()
            .map(|m| (m.name.as_str(), m.base_color[0]))
            .collect();
        assert_eq!(
            names,
            [("red", 1.0), ("wood", 0.5), ("red", 0.9), ("steel", 0.2)]
        );
        assert!(table.iter().enumerate().all(|(i, m)| m.id == i as u16));
        assert_eq!(maps, [vec![0, 1], vec![1, 2, 3]]);
        assert_eq!(none, None);
        let (table, maps, none) = merge_materials(&[None, Some(&colour_only), Some(&b)]);
        assert_eq!(table.len(), 4);
        assert_eq!(table[3].name, NO_MATERIAL);
        assert_eq!(table[3].base_color, [0.0; 4]);
        assert_eq!(none, Some(3));
        assert_eq!(maps, [vec![], vec![], vec![0, 1, 2]]);
        // No operand with materials: no table, no "none".
        let (table, _, none) = merge_materials(&[None, Some(&colour_only)]);
        assert!(table.is_empty() && none.is_none());
    }
}
