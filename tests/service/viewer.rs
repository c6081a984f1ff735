//! The viewer page (`GET /v1/volumes/{id}/view`, issue 33) in a real headless browser: Debian's
//! Chromium loads the page of a stored volume from the real server (three.js from the binary,
//! no internet), and the test reads what it drew — the DOM after the scripts ran (the canvas,
//! the mesh's triangle count, no errors) and a screenshot (the model's colour in the middle of
//! the canvas, not the background). Chromium comes from `scripts/provision.sh` (`chromium`);
//! without it the browser part is skipped with a notice, unless VOXD_REQUIRE_CHROMIUM=1.

use super::*;

/// The browser, or `None` with a notice.
fn chromium() -> Option<PathBuf> {
    let path = PathBuf::from(std::env::var("VOXD_CHROMIUM").unwrap_or("/usr/bin/chromium".into()));
    if path.exists() {
        return Some(path);
    }
    assert!(
        std::env::var("VOXD_REQUIRE_CHROMIUM").as_deref() != Ok("1"),
        "{} is required here (scripts/provision.sh installs chromium)",
        path.display()
    );
    eprintln!("NOTICE: no {}; skipping the browser checks", path.display());
    None
}

/// What a failure shows of a dumped page: its body's tag (the data- attributes the page sets)
/// and its status line, not the whole page.
fn page_state(dom: &str) -> String {
    let tag = |open: &str, close: &str| {
        dom.split_once(open)
            .map(|(_, rest)| rest.split_once(close).map_or(rest, |(a, _)| a))
            .map(|s| s.chars().take(300).collect::<String>())
            .unwrap_or_else(|| "(none)".into())
    };
    format!(
        "<body{}> status: {:?} ({} bytes of page)",
        tag("<body", ">"),
        tag("id=\"status\"", "</div>"),
        dom.len()
    )
}

/// Runs headless Chromium on `url` with `args` (in its own process group, killed after, 120 s
/// at most): its stdout.
fn browse(chromium: &Path, profile: &Path, url: &str, args: &[&str]) -> String {
    use std::os::unix::process::CommandExt;
    let mut child = Command::new("timeout")
        .args(["-k", "5", "120"])
        .arg(chromium)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--window-size=1000,700",
            "--virtual-time-budget=20000",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .args(args)
        .arg(url)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .process_group(0)
        .spawn()
        .expect("chromium starts");
    let mut out = String::new();
    child
        .stdout
        .take()
        .unwrap()
        .read_to_string(&mut out)
        .unwrap();
    let status = child.wait().unwrap();
    let _ = Command::new("kill")
        .args(["-KILL", "--", &format!("-{}", child.id())])
        .stderr(Stdio::null())
        .status();
    assert!(status.success(), "chromium: {status}");
    out
}

#[test]
fn the_viewer_page_draws_the_volume_in_a_headless_browser() {
    let dir = tmpdir("viewer");
    let srv = Server::start(&dir, &[]);
    let v = srv.created(
        "/v1/voxelize?resolution=48&name=spot&wait=60",
        &[("Content-Type", "model/obj")],
        &std::fs::read(data("spot.obj")).unwrap(),
    );
    let id = v["id"].as_str().unwrap();
    // The page and its files, from the binary.
    let page = srv
        .req("GET", &format!("/v1/volumes/{id}/view"), &[], &[])
        .ok(200);
    assert_eq!(
        page.header("content-type"),
        Some("text/html; charset=utf-8")
    );
    assert!(
        page.header("content-security-policy")
            .unwrap()
            .contains("default-src 'self'")
    );
    let html = String::from_utf8_lossy(&page.body).to_string();
    assert!(html.contains("/v1/viewer/three.module.min.js"));
    for f in [
        "three.module.min.js",
        "three.core.min.js",
        "OrbitControls.js",
        "LICENSE-three.txt",
    ] {
        let r = srv.req("GET", &format!("/v1/viewer/{f}"), &[], &[]).ok(200);
        assert!(r.body.len() > 1000, "{f}");
    }
    srv.req("GET", "/v1/viewer/secret.txt", &[], &[])
        .problem(404, "not-found");
    srv.req("GET", "/v1/volumes/..%2Fx/view", &[], &[])
        .problem(404, "not-found");
    let Some(chromium) = chromium() else { return };
    let url = format!("http://{}/v1/volumes/{id}/view", srv.addr);
    let dom = drawn_dom(&chromium, &dir, &url);
    assert!(dom.contains("<canvas"), "no canvas: {}", page_state(&dom));
    assert!(!dom.contains("data-errors"), "errors: {}", page_state(&dom));
    assert!(
        dom.contains("data-drawn=\"yes\""),
        "not drawn: {}",
        page_state(&dom)
    );
    let tris: u64 = dom
        .split("data-triangles=\"")
        .nth(1)
        .and_then(|s| s.split('"').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no triangle count: {}", page_state(&dom)));
    assert!(tris > 1000, "{tris}");
    let dims: Vec<String> = v["grid"]["dims"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d.to_string())
        .collect();
    assert!(
        dom.contains(&dims.join(" × ")),
        "no grid {dims:?}: {}",
        page_state(&dom)
    );
    let (centre, _) = screenshot(&chromium, &dir, &url);
    // The model's orange, lit: red well over blue.
    let model = centre
        .iter()
        .filter(|p| p[0] > 80 && i32::from(p[0]) - i32::from(p[2]) > 40)
        .count();
    assert!(
        model > 3200,
        "only {model} of 6400 pixels at the centre show the model"
    );
    let _ = std::fs::copy(dir.join("view.png"), scratch_root().join("viewer.png"));
    srv.stop();
}

/// The DOM once the scripts ran. A page not drawn yet when the browser's time budget ran out (a
/// loaded machine) is loaded again, 3 times at most.
fn drawn_dom(chromium: &Path, dir: &Path, url: &str) -> String {
    let mut dom = String::new();
    for attempt in 0..3 {
        dom = browse(
            chromium,
            &dir.join(format!("profile-dom-{attempt}")),
            url,
            &["--dump-dom"],
        );
        if dom.contains("data-drawn=\"yes\"") || dom.contains("data-errors") {
            break;
        }
        eprintln!("attempt {attempt}: not drawn yet: {}", page_state(&dom));
    }
    dom
}

/// A screenshot of the page (`dir/view.png`): the 80 × 80 pixels at the middle of the 3D view
/// (the page's left 700 of 1000 pixels), checked to have the background (#1d2025) at its corner.
fn screenshot(chromium: &Path, dir: &Path, url: &str) -> (Vec<[u8; 3]>, PathBuf) {
    let shot = dir.join("view.png");
    browse(
        chromium,
        &dir.join("profile-shot"),
        url,
        &[&format!("--screenshot={}", shot.display())],
    );
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&shot).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let ch = info.color_type.samples();
    let px = |x: usize, y: usize| {
        let i = (y * info.width as usize + x) * ch;
        [buf[i], buf[i + 1], buf[i + 2]]
    };
    assert_eq!(px(10, 10), [0x1d, 0x20, 0x25]);
    let (cx, cy) = (350, info.height as usize / 2);
    let mut centre = vec![];
    for y in cy - 40..cy + 40 {
        for x in cx - 40..cx + 40 {
            centre.push(px(x, y));
        }
    }
    (centre, shot)
}

/// A volume with colours is drawn in its colours: a blue box (a zipped OBJ whose material is
/// blue, `color=true`) shows blue at the centre of the view, where a volume without colours is
/// orange, and the page says it uses vertex colours.
#[test]
fn the_viewer_page_shows_a_volumes_colours() {
    let dir = tmpdir("viewer-colour");
    let srv = Server::start(&dir, &[]);
    let obj = material_boxes_obj("m.mtl", &[("blue", [0.0; 3], [1.0; 3])]);
    let body = super::zip_upload::zip_of(&[
        ("box.obj", obj.as_bytes()),
        ("m.mtl", b"newmtl blue\nKd 0.1 0.3 1\n"),
    ]);
    let v = srv.created(
        "/v1/voxelize?resolution=24&color=true&wait=60",
        &[("Content-Type", "application/zip")],
        &body,
    );
    let id = v["id"].as_str().unwrap();
    // The mesh the page loads has COLOR_0.
    let glb = srv
        .req(
            "GET",
            &format!("/v1/volumes/{id}/mesh?format=glb&algorithm=surface-nets"),
            &[],
            &[],
        )
        .ok(200)
        .body;
    let g = gltf::Gltf::from_slice(&glb).unwrap();
    let prim = g.meshes().next().unwrap().primitives().next().unwrap();
    assert!(prim.get(&gltf::Semantic::Colors(0)).is_some());
    let Some(chromium) = chromium() else { return };
    let url = format!("http://{}/v1/volumes/{id}/view", srv.addr);
    let dom = drawn_dom(&chromium, &dir, &url);
    assert!(!dom.contains("data-errors"), "errors: {}", page_state(&dom));
    assert!(
        dom.contains("data-colours=\"yes\""),
        "no colours: {}",
        page_state(&dom)
    );
    let (centre, _) = screenshot(&chromium, &dir, &url);
    let blue = centre
        .iter()
        .filter(|p| p[2] > 60 && i32::from(p[2]) - i32::from(p[0]) > 40)
        .count();
    assert!(
        blue > 3200,
        "only {blue} of 6400 pixels at the centre are blue"
    );
    srv.stop();
}
