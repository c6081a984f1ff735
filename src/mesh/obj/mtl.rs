//! Wavefront material libraries (`.mtl`): `newmtl` names a material, `Kd r g b` is its
//! diffuse colour, `d a` its opacity (or `Tr t`, 1 − t), and `map_Kd [options] file` its
//! diffuse texture, which the MTL specification multiplies by `Kd` (as glTF multiplies its base
//! colour texture by the factor). Of `map_Kd`'s options, `-o u v` (offset), `-s u v` (scale:
//! the coordinates become `s·vt + o`, as Blender's importer maps them) and `-clamp on` (clamp to
//! edge instead of repeat) are honoured; the others are skipped with their arguments.
//!
//! Read only for an OBJ loaded from a file (`ExternalResources::BesideFile`), from relative
//! paths that stay beside it, or from a zip upload (`ExternalResources::Archive`, its entries).
//! A library is read up to [`MAX_BYTES`], a texture up to the mesh's texture limit; one that is
//! missing or unreadable is skipped with a warning (the materials stay white, the texture is
//! left out), as OBJ viewers do. A texture's path is relative to its library's directory.

use std::collections::HashMap;

use crate::mesh::ExternalResources;

/// The largest `.mtl` read.
pub const MAX_BYTES: u64 = 16 << 20;

/// A material of a library.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct MtlMaterial {
    /// Linear RGBA in [0, 1] (`Kd`, `d`/`Tr`).
    pub colour: [f32; 4],
    pub map: Option<MapKd>,
}

/// A `map_Kd` statement.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct MapKd {
    /// The image's path, relative to the OBJ's directory (the library's directory joined
    /// with the file name, `/`-separated).
    pub path: String,
    pub scale: [f32; 2],
    pub offset: [f32; 2],
    pub clamp: bool,
}

/// The file `rel` (relative to the OBJ's directory) from `external`, at most `max` bytes.
/// `Err`: why it was not read (for the warning).
pub(super) fn read(external: &ExternalResources, rel: &str, max: u64) -> Result<Vec<u8>, String> {
    match external {
        ExternalResources::Deny => Err("files beside the mesh are not read here".into()),
        ExternalResources::Archive(a) => match a.get(rel) {
            Some(t) if t.len() as u64 <= max => Ok(t.to_vec()),
            Some(t) => Err(format!("{} bytes, over the limit of {max}", t.len())),
            None => Err("not in the uploaded archive".into()),
        },
        ExternalResources::BesideFile(dir) => {
            let Some(path) = crate::mesh::beside(dir, &rel.replace('\\', "/")) else {
                return Err("a path outside the OBJ's directory is not read".into());
            };
            match std::fs::metadata(&path) {
                Ok(m) if m.len() > max => {
                    Err(format!("{} bytes, over the limit of {max}", m.len()))
                }
                Ok(_) => std::fs::read(&path).map_err(|e| e.to_string()),
                Err(e) => Err(e.to_string()),
            }
        }
    }
}

/// The materials of the libraries `libs`, by name (a later definition wins).
pub(super) fn materials(
    libs: &[Vec<u8>],
    external: &ExternalResources,
) -> HashMap<String, MtlMaterial> {
    let mut out = HashMap::new();
    for lib in libs {
        let name = String::from_utf8_lossy(lib);
        match read(external, &name, MAX_BYTES) {
            Ok(text) => {
                let dir = match name.replace('\\', "/").rsplit_once('/') {
                    Some((d, _)) => format!("{d}/"),
                    None => String::new(),
                };
                parse(&text, &dir, &mut out)
            }
            Err(e) => tracing::warn!(mtllib = %name, "material library not read: {e}"),
        }
    }
    out
}

/// Adds the materials of `text` (a library in directory `dir`, `""` or ending in `/`) to
/// `out`.
fn parse(text: &[u8], dir: &str, out: &mut HashMap<String, MtlMaterial>) {
    let mut current: Option<String> = None;
    let unit = |v: &str| {
        v.parse::<f32>()
            .ok()
            .filter(|v| !v.is_nan())
            .map(|v| v.clamp(0.0, 1.0))
    };
    for line in String::from_utf8_lossy(text).lines() {
        let mut words = line.split_whitespace();
        let key = words.next();
        if key == Some("newmtl") {
            let name = words.collect::<Vec<_>>().join(" ");
            out.insert(
                name.clone(),
                MtlMaterial {
                    colour: [1.0; 4],
                    map: None,
                },
            );
            current = Some(name);
            continue;
        }
        let Some(m) = current.as_ref().and_then(|n| out.get_mut(n)) else {
            continue;
        };
        let c = &mut m.colour;
        match key {
            Some(key @ ("Kd" | "d" | "Tr")) => {
                let v: Vec<f32> = words.filter_map(unit).collect();
                match (key, v.as_slice()) {
                    ("Kd", [r, g, b, ..]) => (c[0], c[1], c[2]) = (*r, *g, *b),
                    ("d", [a, ..]) => c[3] = *a,
                    ("Tr", [t, ..]) => c[3] = 1.0 - t,
                    _ => {}
                }
            }
            Some("map_Kd") => m.map = map_kd(&words.collect::<Vec<_>>(), dir),
            _ => {}
        }
    }
}

/// A `map_Kd` statement's options and file name (the words after `map_Kd`).
fn map_kd(words: &[&str], dir: &str) -> Option<MapKd> {
    let mut map = MapKd {
        path: String::new(),
        scale: [1.0; 2],
        offset: [0.0; 2],
        clamp: false,
    };
    let mut i = 0;
    let number = |w: &str| w.parse::<f32>().ok().filter(|v| v.is_finite());
    while i < words.len() && words[i].starts_with('-') {
        let opt = words[i];
        i += 1;
        match opt {
            // Up to three numbers (u, v, w).
            "-o" | "-s" | "-t" => {
                let mut v = vec![];
                while v.len() < 3 && i < words.len() {
                    match number(words[i]) {
                        Some(x) => (v.push(x), i += 1),
                        None => break,
                    };
                }
                let target = match opt {
                    "-o" => Some((&mut map.offset, 0.0)),
                    "-s" => Some((&mut map.scale, 1.0)),
                    _ => None,
                };
                if let Some((t, default)) = target {
                    *t = [
                        v.first().copied().unwrap_or(default),
                        v.get(1).copied().unwrap_or(default),
                    ];
                }
            }
            "-clamp" => {
                map.clamp = words.get(i) == Some(&"on");
                i += 1;
            }
            "-mm" => i += 2,
            "-blendu" | "-blendv" | "-cc" | "-boost" | "-texres" | "-imfchan" | "-bm" => i += 1,
            _ => {} // unknown: taken as a flag without arguments
        }
    }
    let file = words.get(i..)?.join(" ");
    (!file.is_empty()).then(|| {
        map.path = format!("{dir}{}", file.replace('\\', "/"));
        map
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kd_and_opacity_by_name() {
        let mut out = HashMap::new();
        parse(
            b"# a library\nnewmtl red paint\nKd 1 0 0\nd 0.5\nnewmtl blue\nKd 0 0 2\nTr 0.25\nKd x\nnewmtl plain\n",
            "",
            &mut out,
        );
        assert_eq!(out["red paint"].colour, [1.0, 0.0, 0.0, 0.5]);
        assert_eq!(out["blue"].colour, [0.0, 0.0, 1.0, 0.75]);
        assert_eq!(out["plain"].colour, [1.0; 4]);
        assert!(out.values().all(|m| m.map.is_none()));
        assert_eq!(out.len(), 3);
    }

    #[test]
    fn map_kd_with_its_options_and_a_name_with_spaces() {
        let mut out = HashMap::new();
        parse(
            b"newmtl a\nmap_Kd wood.png\nnewmtl b\nKd 0.5 0.5 0.5\nmap_Kd -o 0.25 0.5 -s 2 3 1 -clamp on -bm 0.3 -mm 0 1 my tex\\x.jpg\nnewmtl c\nmap_Kd -s 2\n",
            "textures/",
            &mut out,
        );
        assert_eq!(
            out["a"].map,
            Some(MapKd {
                path: "textures/wood.png".into(),
                scale: [1.0; 2],
                offset: [0.0; 2],
                clamp: false
            })
        );
        let b = &out["b"];
        assert_eq!(b.colour, [0.5, 0.5, 0.5, 1.0]);
        assert_eq!(
            b.map,
            Some(MapKd {
                path: "textures/my tex/x.jpg".into(),
                scale: [2.0, 3.0],
                offset: [0.25, 0.5],
                clamp: true
            })
        );
        // Options and no file: no texture.
        assert_eq!(out["c"].map, None);
    }
}
