//! Wavefront material libraries (`.mtl`), for the base colour of each `usemtl` name: `newmtl`
//! names a material, `Kd r g b` is its diffuse colour, `d a` its opacity (or `Tr t`, 1 − t).
//! Read only for an OBJ loaded from a file (`ExternalResources::BesideFile`), from relative
//! paths that stay beside it, or from a zip upload (`ExternalResources::Archive`, its entries), at most [`MAX_BYTES`] each; a library that is missing or
//! unreadable is skipped with a warning (its materials stay white), as OBJ viewers do. Textures
//! (`map_Kd`) are not read yet.

use std::collections::HashMap;
use std::path::{Component, Path};

use crate::mesh::ExternalResources;

/// The largest `.mtl` read.
pub const MAX_BYTES: u64 = 16 << 20;

/// Each material's base colour (linear RGBA in [0, 1]) from the libraries `libs`.
pub(super) fn base_colours(
    libs: &[Vec<u8>],
    external: &ExternalResources,
) -> HashMap<String, [f32; 4]> {
    let mut out = HashMap::new();
    let dir = match external {
        ExternalResources::BesideFile(dir) => dir,
        ExternalResources::Archive(a) => {
            for lib in libs {
                let name = String::from_utf8_lossy(lib);
                match a.get(&name) {
                    Some(t) if t.len() as u64 <= MAX_BYTES => parse(t, &mut out),
                    Some(t) => {
                        tracing::warn!(mtllib = %name, bytes = t.len(), "material library over 16 MiB skipped")
                    }
                    None => {
                        tracing::warn!(mtllib = %name, "material library not in the uploaded archive")
                    }
                }
            }
            return out;
        }
        ExternalResources::Deny => return out,
    };
    for lib in libs {
        let name = String::from_utf8_lossy(lib);
        let rel = Path::new(name.as_ref());
        if name.contains(':')
            || !rel
                .components()
                .all(|c| matches!(c, Component::Normal(_) | Component::CurDir))
        {
            tracing::warn!(mtllib = %name, "a material library outside the OBJ's directory is not read");
            continue;
        }
        let path = dir.join(rel);
        let text = match std::fs::metadata(&path) {
            Ok(m) if m.len() > MAX_BYTES => {
                tracing::warn!(path = %path.display(), bytes = m.len(), "material library over 16 MiB skipped");
                continue;
            }
            Ok(_) => std::fs::read(&path),
            Err(e) => Err(e),
        };
        match text {
            Ok(t) => parse(&t, &mut out),
            Err(e) => {
                tracing::warn!(path = %path.display(), "material library not read: {e}")
            }
        }
    }
    out
}

/// Adds the base colours of the materials of `text` to `out` (a later definition wins).
fn parse(text: &[u8], out: &mut HashMap<String, [f32; 4]>) {
    let mut current: Option<String> = None;
    let unit = |v: &str| {
        v.parse::<f32>()
            .ok()
            .filter(|v| !v.is_nan())
            .map(|v| v.clamp(0.0, 1.0))
    };
    for line in String::from_utf8_lossy(text).lines() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("newmtl") => {
                let name = words.collect::<Vec<_>>().join(" ");
                out.insert(name.clone(), [1.0; 4]);
                current = Some(name);
            }
            Some(key @ ("Kd" | "d" | "Tr")) => {
                let Some(c) = current.as_ref().and_then(|n| out.get_mut(n)) else {
                    continue;
                };
                let v: Vec<f32> = words.filter_map(unit).collect();
                match (key, v.as_slice()) {
                    ("Kd", [r, g, b, ..]) => (c[0], c[1], c[2]) = (*r, *g, *b),
                    ("d", [a, ..]) => c[3] = *a,
                    ("Tr", [t, ..]) => c[3] = 1.0 - t,
                    _ => {}
                }
            }
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kd_and_opacity_by_name() {
        let mut out = HashMap::new();
        parse(
            b"# a library\nnewmtl red paint\nKd 1 0 0\nd 0.5\nnewmtl blue\nKd 0 0 2\nTr 0.25\nKd x\nnewmtl plain\n",
            &mut out,
        );
        assert_eq!(out["red paint"], [1.0, 0.0, 0.0, 0.5]);
        assert_eq!(out["blue"], [0.0, 0.0, 1.0, 0.75]);
        assert_eq!(out["plain"], [1.0; 4]);
        assert_eq!(out.len(), 3);
    }
}
