//! Which of a channel volume's attributes a download holds (`?attributes=` on the data route):
//! `.npy` and `.raw` hold occupancy (0/1) unless asked for one channel (`rgba`:
//! `uint8 (X, Y, Z, 4)`, `material`: `uint16 (X, Y, Z)`), `indices` the set voxels' indices
//! unless asked for a channel too (then an `.npz` of both, [`is_npz`]), the other
//! formats that list or draw voxels hold the bits with the colours they show (`.vox`'s palette,
//! `points`' colours), and `.vxl` holds everything.

use super::error::{Error, ErrorKind, Result};
use super::store::VolumeMeta;
use crate::codec::VolumeFormat;
use crate::volume::{Attributed, Volume, VolumeKind};

/// Checks `attributes` (a channel name) against a download of a volume described by `meta` in
/// `format`, before anything is read: only `.npy` and `.raw` take it, and only for a channel
/// the volume has.
pub fn check(meta: &VolumeMeta, format: VolumeFormat, attributes: Option<&str>) -> Result<()> {
    let Some(name) = attributes else {
        return Ok(());
    };
    let channels = meta
        .attributes
        .as_ref()
        .map(|a| a.channels.clone())
        .unwrap_or_default();
    check_channels(meta.kind, &channels, format, name)
}

fn check_channels(
    kind: VolumeKind,
    channels: &[String],
    format: VolumeFormat,
    name: &str,
) -> Result<()> {
    if !matches!(
        format,
        VolumeFormat::Npy | VolumeFormat::Raw | VolumeFormat::Indices
    ) {
        return Err(Error::invalid(format!(
            "attributes={name} applies to format=npy, raw and indices only (format={} holds {})",
            format.name(),
            match format {
                VolumeFormat::Vox | VolumeFormat::Points => "the colours by itself",
                VolumeFormat::Vxl => "every channel",
                _ => "occupancy only",
            }
        )));
    }
    if kind != VolumeKind::Channels {
        return Err(Error::new(
            ErrorKind::WrongVolumeKind,
            format!(
                "attributes={name}: a {kind} volume has no attribute channels (voxelize with color=true or material=true)"
            ),
        ));
    }
    if !channels.iter().any(|c| c == name) {
        return Err(Error::invalid(format!(
            "attributes={name}: the volume's channels are {}",
            channels.join(", ")
        )));
    }
    Ok(())
}

/// Does a download in `format` with `attributes` come as an `.npz` (indices with a channel)?
pub fn is_npz(format: VolumeFormat, attributes: Option<&str>) -> bool {
    format == VolumeFormat::Indices && attributes.is_some()
}

/// What of `v` a download in `format` holds (module docs); `attributes` checked as [`check`]
/// does.
pub fn select(v: Volume, format: VolumeFormat, attributes: Option<&str>) -> Result<Volume> {
    let Volume::Channels(a) = v else {
        if let Some(name) = attributes {
            check_channels(v.kind(), &[], format, name)?;
        }
        return Ok(v);
    };
    match attributes {
        Some(name) => {
            let names: Vec<String> = a.channels().iter().map(|c| c.name.clone()).collect();
            check_channels(VolumeKind::Channels, &names, format, name)?;
            let values = a.channel(name).expect("checked").values.clone();
            let mut one = Attributed::new(a.into_bits());
            one.add(name, values).expect("one value per set voxel");
            Ok(Volume::Channels(one))
        }
        None => Ok(match format {
            VolumeFormat::Vxl | VolumeFormat::Vox | VolumeFormat::Points => Volume::Channels(a),
            _ => Volume::Bits(a.into_bits()),
        }),
    }
}
