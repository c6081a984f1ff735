//! Parses one mesh many times and prints the time per parse and per diagnosis, for profiling
//! the service's small jobs: `cargo run --release --example parse_small -- MESH [N]`. Run it
//! with `RAYON_NUM_THREADS=1` for the time of one core.
use std::time::Instant;

fn main() {
    // On a worker of rayon's pool, as the service runs it (a parse from outside the pool would
    // also time the wake-up of a worker for every parallel step).
    rayon::scope(|_| run());
}

fn run() {
    let mut args = std::env::args().skip(1);
    let path = args.next().expect("usage: parse_small MESH [N]");
    let n: usize = args.next().map_or(2000, |v| v.parse().expect("N"));
    let bytes = std::fs::read(&path).expect("read the mesh");
    let format = voxd::mesh::Format::from_path(std::path::Path::new(&path));
    let opts = voxd::mesh::LoadOptions::default();
    let t = Instant::now();
    let mut tris = 0;
    for _ in 0..n {
        tris += voxd::mesh::load_bytes(&bytes, format, &opts)
            .expect("parse")
            .triangles()
            .len();
    }
    let parse = t.elapsed().as_secs_f64() / n as f64;
    let mesh = voxd::mesh::load_bytes(&bytes, format, &opts).expect("parse");
    let t = Instant::now();
    for _ in 0..n {
        std::hint::black_box(voxd::mesh::MeshDiagnostics::of(&mesh));
    }
    let diagnose = t.elapsed().as_secs_f64() / n as f64;
    println!(
        "{path}: {} bytes, {} triangles; parse {:.1} us ({:.0} MB/s), diagnose {:.1} us",
        bytes.len(),
        tris / n,
        parse * 1e6,
        bytes.len() as f64 / parse / 1e6,
        diagnose * 1e6
    );
}
