//! `voxd sdf`, `voxd threshold` and `voxd csg` on distance volumes, on files (definitions:
//! docs/methods.md, "Operations on distance volumes"). The oracle: the bit volume the sdf was
//! made from, and the values read back from the files.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use crate::common::run_voxd as voxd;
use crate::common::*;
use voxd::codec::VolumeFormat;
use voxd::volume::Volume;

fn tmp(name: &str) -> PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| tmpdir("distance-cli")).join(name)
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn read(p: &Path) -> Volume {
    let b = std::fs::read(p).unwrap();
    VolumeFormat::sniff(&b).unwrap().decode(&b).unwrap()
}

#[test]
fn sdf_threshold_and_distance_csg_on_the_command_line() {
    let (a, d, t, u) = (
        tmp("dist-a.vxl"),
        tmp("dist-d.vxl"),
        tmp("dist-t.vxl"),
        tmp("dist-u.vxl"),
    );
    let ok = |args: &[&str]| {
        let o = voxd(args);
        assert!(
            o.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    };
    ok(&[
        "voxelize",
        s(&data("Box.gltf")),
        "-o",
        s(&a),
        "--resolution",
        "12",
        "--padding",
        "3",
        "--engine",
        "cpu",
    ]);
    ok(&["sdf", s(&a), "--band", "2", "-o", s(&d)]);
    let (Volume::Bits(bits), Volume::SparseDistance(sdf)) = (read(&a), read(&d)) else {
        panic!("a bit volume and a sparse distance volume")
    };
    let [nx, ny, nz] = bits.dims();
    let vs = bits.grid().voxel_size as f32;
    let mut deep = 0;
    for x in 0..nx {
        for y in 0..ny {
            for z in 0..nz {
                let v = sdf.get(x, y, z);
                assert_eq!(v.is_sign_negative(), bits.get(x, y, z));
                assert!(v.abs() >= vs / 2.0 && v.abs() <= 2.0 * vs);
                deep += (v < -vs) as u64;
            }
        }
    }
    ok(&["threshold", s(&d), "--level", "0", "-o", s(&t)]);
    assert_eq!(read(&t), Volume::Bits(bits.clone()));
    let level = format!("{}", -vs);
    ok(&["threshold", s(&d), "--level", &level, "-o", s(&t)]);
    let Volume::Bits(inner) = read(&t) else {
        panic!()
    };
    assert_eq!(inner.count_ones(), deep);
    assert!(deep > 0 && deep < bits.count_ones());
    ok(&["csg", "union", s(&d), s(&d), "-o", s(&u)]);
    assert_eq!(read(&u), Volume::SparseDistance(sdf));
    // A bit volume is not thresholded; a distance volume is not transformed again.
    let o = voxd(&["threshold", s(&a), "--level", "0", "-o", s(&t)]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("distance volumes"));
    assert!(!voxd(&["sdf", s(&d), "-o", s(&t)]).status.success());
    assert!(
        !voxd(&["sdf", s(&a), "--band", "0", "-o", s(&t)])
            .status
            .success()
    );
}
