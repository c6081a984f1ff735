//! The OBJ reader's own tests: the scanner's numbers against `str::parse` on random tokens, the
//! chunk reader against the plain token-splitting reader it replaced on random OBJ text, the
//! line counts, and index resolution. Not here: whole files against `tobj` and the loaders'
//! behaviour (`tests/loaders.rs`, `mesh/streaming_tests.rs`).

use std::sync::atomic::AtomicUsize;

use super::lexer::*;
use super::parser::*;
use super::*;
use crate::mesh::{MeshError, bad_position, fan, malformed};
use crate::testkit::Rng;

/// The chunk reader before its hand-written scanner and number parsers (tokens by
/// `split`, numbers by `str::parse`): what the new one must give, error for error.
fn parse_chunk_std(
    text: &[u8],
    vbase: usize,
    lbase: usize,
    nv: usize,
    total: Option<usize>,
    shared: &Shared,
) -> Result<Chunk, MeshError> {
    let mut positions = Vec::with_capacity(nv);
    let mut triangles = Vec::new();
    let mut poly: Vec<u32> = Vec::new();
    let mut forward: Option<(usize, i64, usize)> = None;
    let mut reported = 0;
    for (i, raw) in text.split(|&b| b == b'\n').enumerate() {
        let line = raw.trim_ascii();
        let err = |what: &str| malformed("OBJ", format!("line {}: {what}", lbase + i + 1));
        let mut tok = line
            .split(|b| b.is_ascii_whitespace())
            .filter(|t| !t.is_empty());
        match tok.next() {
            Some(b"v") => {
                let mut p = [0.0; 3];
                for c in &mut p {
                    let t = tok.next().ok_or_else(|| err("a vertex needs x, y and z"))?;
                    *c = std::str::from_utf8(t)
                        .ok()
                        .and_then(|s| s.parse().ok())
                        .ok_or_else(|| {
                            err(&format!("{:?} is not a number", String::from_utf8_lossy(t)))
                        })?;
                }
                positions.push(p);
            }
            Some(b"f") => {
                let defined = (vbase + positions.len()) as i64;
                poly.clear();
                for t in tok {
                    let idx = t.split(|&b| b == b'/').next().unwrap_or(t);
                    let n: i64 = std::str::from_utf8(idx)
                        .ok()
                        .and_then(|s| s.parse().ok())
                        .ok_or_else(|| {
                            err(&format!(
                                "{:?} is not a vertex index",
                                String::from_utf8_lossy(t)
                            ))
                        })?;
                    let abs = resolve_index(n, defined, total).map_err(|m| err(&m))?;
                    if abs as i64 >= defined && forward.is_none_or(|f| abs > f.2) {
                        forward = Some((lbase + i + 1, n, abs));
                    }
                    poly.push(abs as u32);
                }
                fan(&poly, &mut triangles);
                if triangles.len() - reported >= REPORT_EVERY {
                    shared.add(triangles.len() - reported)?;
                    reported = triangles.len();
                }
            }
            _ => {} // comments, vt, vn, o, g, s, usemtl, mtllib, l, p, ...
        }
    }
    shared.add(triangles.len() - reported)?;
    let bad = positions.iter().position(bad_position).map(|i| vbase + i);
    // Colours and materials are not compared here (tests/attributes.rs reads them against a
    // plain reading of its own).
    Ok(Chunk {
        positions,
        triangles,
        forward,
        bad,
        colors: vec![],
        names: vec![],
        material: vec![],
        last: INHERITED,
        libs: vec![],
        texcoords: vec![],
        corners: vec![],
        uv_forward: None,
    })
}

fn std_f64(t: &[u8]) -> Option<f64> {
    std::str::from_utf8(t).ok()?.parse().ok()
}

/// A line holding the token `t`.
fn line(t: &[u8]) -> Line<'_> {
    Line {
        text: t,
        end: t.len(),
        at: 0,
    }
}

/// What [`Line::float`] makes of the token `t`.
fn read_float(t: &[u8]) -> Option<f64> {
    line(t).float()?.ok()
}

/// What [`Line::index`] makes of the token `t`.
fn read_index(t: &[u8]) -> Option<i64> {
    line(t).index()?.ok()
}

/// The plain decimals that [`Line::float`] reads itself, written plainly over a whole token
/// (`None` for any other token): the test counts the tokens it takes, so that it is known
/// to exercise that path, and checks its value too.
fn plain_decimal(t: &[u8]) -> Option<f64> {
    let (neg, d) = match t.first()? {
        b'-' => (true, &t[1..]),
        b'+' => (false, &t[1..]),
        _ => (false, t),
    };
    let mut m: u64 = 0;
    let mut i = 0;
    while i < d.len() && d[i].is_ascii_digit() {
        m = m.wrapping_mul(10).wrapping_add((d[i] - b'0') as u64);
        i += 1;
    }
    let whole = i;
    let mut frac = 0;
    if i < d.len() && d[i] == b'.' {
        i += 1;
        let start = i;
        while i < d.len() && d[i].is_ascii_digit() {
            m = m.wrapping_mul(10).wrapping_add((d[i] - b'0') as u64);
            i += 1;
        }
        frac = i - start;
    }
    // 19 digits cannot overflow u64 (so the wrapping above never wraps when this holds).
    let digits = whole + frac;
    if i != d.len() || digits == 0 || digits > 19 || m > 1 << 53 || frac > 22 {
        return None;
    }
    let v = m as f64 / POW10[frac];
    Some(if neg { -v } else { v })
}

fn digits(r: &mut Rng, n: usize) -> String {
    (0..n).map(|_| (b'0' + r.below(10) as u8) as char).collect()
}

/// A token like those of OBJ files and their corners: signs, points, exponents, long
/// digit runs, special values and garbage.
fn number_token(r: &mut Rng) -> String {
    match r.below(8) {
        0 => r
            .pick(&[
                "inf",
                "-inf",
                "+inf",
                "Infinity",
                "-infinity",
                "NaN",
                "nan",
                "-nan",
                "+",
                "-",
                ".",
                "-.",
                "+.",
                "",
                "e5",
                ".e1",
                "1e",
                "1e+",
                "0x10",
                "1_0",
                "1,5",
                "--1",
                "+-1",
                "1.2.3",
                "١",
                "1\u{a0}",
                "1\x0b",
                "1.5\x00",
            ])
            .to_string(),
        1 => {
            let v = f64::from_bits(r.next_u64());
            match r.below(4) {
                0 => format!("{v}"),
                1 => format!("{v:e}"),
                2 => format!("{v:.7}"),
                _ => format!("{:?}", v as f32),
            }
        }
        2 => {
            // Subnormals and values near the ends of the range.
            let v = f64::from_bits(r.next_u64() % (1 << 53));
            let w = f64::MAX / (1 + r.below(1000)) as f64;
            format!("{}", if r.below(2) == 0 { v } else { w })
        }
        _ => {
            let sign = r.pick(&["", "", "-", "+"]);
            let most = if r.below(4) == 0 { 25 } else { 4 };
            let n = r.below(most);
            let whole = digits(r, n);
            let point = r.pick(&["", ".", ".", "."]);
            let most = if r.below(4) == 0 { 30 } else { 9 };
            let n = r.below(most);
            let frac = digits(r, n);
            let exp = match r.below(6) {
                0 => format!("e{}", r.below(40) as i64 - 20),
                1 => format!("E+{}", r.below(400)),
                _ => String::new(),
            };
            format!("{sign}{whole}{point}{frac}{exp}")
        }
    }
}

#[test]
fn floats_read_as_std_reads_them() {
    let fixed = [
        "0",
        "-0",
        "+0",
        "-0.0",
        "0.",
        "-.0",
        ".5",
        "5.",
        "+.5",
        "-5.",
        "0.0081780",
        "-0.0496510",
        "1.7976931348623157e308",
        "4.9e-324",
        "9007199254740992",
        "9007199254740993",
        "9007199254740993.0",
        "0.9007199254740993",
        "1234567890123456789",
        "12345678901234567890",
        "0.1",
        "0.2",
        "0.3",
        "3.14159265358979",
        "0.0000000000000000000001",
        "0.00000000000000000000001",
        "1e22",
        "1e23",
    ];
    for t in fixed {
        let (a, b) = (read_float(t.as_bytes()), std_f64(t.as_bytes()));
        assert_eq!(a.map(f64::to_bits), b.map(f64::to_bits), "{t:?}");
    }
    let mut r = Rng::new(0x9e37_79b9_7f4a_7c15);
    let mut fast = 0;
    for _ in 0..300_000 {
        let t = number_token(&mut r);
        let (a, b) = (read_float(t.as_bytes()), std_f64(t.as_bytes()));
        // NaN == NaN by bits: the standard parser's NaN is one value.
        assert_eq!(a.map(f64::to_bits), b.map(f64::to_bits), "{t:?}");
        if let Some(p) = plain_decimal(t.as_bytes()) {
            assert_eq!(Some(p.to_bits()), b.map(f64::to_bits), "{t:?}");
            fast += 1;
        }
    }
    // The fast path is taken for most of them (so it is what is being tested).
    assert!(fast > 100_000, "{fast}");
    // Not UTF-8: refused like the standard parser refuses it.
    assert_eq!(read_float(b"1\xff"), None);
    assert_eq!(read_float(b"\xff"), None);
}

#[test]
fn indices_read_as_std_reads_them() {
    let std_i64 = |t: &[u8]| -> Option<i64> { std::str::from_utf8(t).ok()?.parse().ok() };
    let mut r = Rng::new(7);
    let fixed = [
        "",
        "+",
        "-",
        "0",
        "-0",
        "+0",
        "1",
        "+1",
        "-1",
        "007",
        "1a",
        "--1",
        "+-1",
        "999999999999999999",
        "9223372036854775807",
        "9223372036854775808",
        "-9223372036854775808",
        "-9223372036854775809",
        "1.0",
        " 1",
        "\u{ff}",
    ];
    let mut tokens: Vec<String> = fixed.iter().map(|t| t.to_string()).collect();
    for _ in 0..100_000 {
        let sign = r.pick(&["", "", "-", "+", "--"]);
        let most = if r.below(8) == 0 { 22 } else { 8 };
        let n = r.below(most);
        let tail = r.pick(&["", "", "", "", "x", "."]);
        tokens.push(format!("{sign}{}{tail}", digits(&mut r, n)));
    }
    for t in tokens {
        // A line's token has no whitespace around it (" 1" is the token "1").
        let token = t.as_bytes().trim_ascii();
        assert_eq!(read_index(t.as_bytes()), std_i64(token), "{t:?}");
    }
}

/// Random OBJ text: vertices written many ways, faces with every index form (some out of
/// range, zero, negative, malformed), other statements, blank lines, odd whitespace.
fn obj_text(r: &mut Rng) -> Vec<u8> {
    let mut s = String::new();
    let mut vertices = 0i64;
    for _ in 0..r.below(60) {
        let ws = |r: &mut Rng| r.pick(&[" ", " ", " ", "  ", "\t", " \t ", "\x0c", "\r"]);
        let lead = r.pick(&["", "", "", "", " ", "\t", "\r"]);
        s += lead;
        match r.below(10) {
            0..=3 => {
                s += "v";
                for _ in 0..[3, 3, 3, 3, 3, 4, 6, 2, 0][r.below(9)] {
                    s += ws(r);
                    s += &if r.below(30) == 0 {
                        number_token(r)
                    } else {
                        let v = (r.next_u64() % 2_000_001) as f64 / 1e6 - 1.0;
                        format!("{v}")
                    };
                }
                vertices += 1;
            }
            4..=6 => {
                s += r.pick(&["f", "f", "f", "f", "fo", "F"]);
                for _ in 0..r.below(6) {
                    s += ws(r);
                    let n = match r.below(12) {
                        0 => 0,
                        1 => -(r.below(vertices as usize + 2) as i64),
                        2 => vertices + 1 + r.below(3) as i64,
                        _ => 1 + r.below(vertices.max(1) as usize) as i64,
                    };
                    s += &match r.below(12) {
                        0 => format!("{n}/{n}"),
                        1 => format!("{n}//{n}"),
                        2 => format!("{n}/1/2"),
                        3 => format!("+{n}"),
                        4 if r.below(4) == 0 => r
                            .pick(&[
                                "x", "/1", "1x", "-", "", "+/", "-/2", "1x/2", "1/x", "1/\x0b2",
                                "1\x0b", "\x00", "1/2\x01x",
                            ])
                            .into(),
                        // Long digit runs, around where the fast path hands over.
                        5 if r.below(4) == 0 => {
                            let sign = r.pick(&["", "-", "+"]);
                            let n = 16 + r.below(6);
                            let tail = r.pick(&["", "/1", "//2", "x"]);
                            format!("{sign}{}{tail}", digits(r, n))
                        }
                        _ => format!("{n}"),
                    };
                }
            }
            7 => {
                s += r.pick(&[
                    "# v 1 2 3",
                    "vt 0.5 0.5",
                    "vn 0 0 1",
                    "o a",
                    "g b",
                    "s 1",
                    "l 1 2",
                    "v",
                    "f",
                    "g a\\",
                    "# \\ x",
                ])
            }
            _ => {}
        }
        if r.below(3) == 0 {
            s += ws(r);
        }
        s += r.pick(&["\n", "\n", "\n", "\r\n", "\n\n"]);
    }
    if r.below(2) == 0 {
        s.pop();
    }
    s.into_bytes()
}

type Parsed = Result<
    (
        Vec<[u64; 3]>,
        Vec<[u32; 3]>,
        Option<(usize, i64, usize)>,
        Option<usize>,
    ),
    MeshError,
>;

/// A chunk reader: [`parse_chunk`] or [`parse_chunk_std`].
type Reader = fn(&[u8], usize, usize, usize, Option<usize>, &Shared) -> Result<Chunk, MeshError>;

/// [`parse_chunk`] without texture coordinates' base (none are kept: `Shared::uv` is off).
fn parse_chunk_plain(
    text: &[u8],
    vbase: usize,
    lbase: usize,
    nv: usize,
    total: Option<usize>,
    shared: &Shared,
) -> Result<Chunk, MeshError> {
    parse_chunk(text, vbase, 0, lbase, nv, total, shared)
}

fn run(f: Reader, text: &[u8], vbase: usize, total: Option<usize>, max_triangles: usize) -> Parsed {
    let shared = Shared {
        triangles: AtomicUsize::new(0),
        max_triangles,
        uv: false,
    };
    f(text, vbase, 3, 0, total, &shared).map(|c| {
        (
            c.positions.iter().map(|p| p.map(f64::to_bits)).collect(),
            c.triangles,
            c.forward,
            c.bad,
        )
    })
}

#[test]
fn chunks_read_as_before() {
    let mut r = Rng::new(0x5eed);
    let (mut ok, mut errors) = (0, 0);
    for case in 0..20_000 {
        let text = obj_text(&mut r);
        let vbase = [0, 0, 5, 1 << 20][r.below(4)];
        let total = [None, None, Some(vbase + 10), Some(vbase + 100)][r.below(4)];
        let max = [usize::MAX, usize::MAX, 3][r.below(3)];
        let new = run(parse_chunk_plain, &text, vbase, total, max);
        let old = run(parse_chunk_std, &text, vbase, total, max);
        assert_eq!(
            new,
            old,
            "case {case}: {:?}",
            String::from_utf8_lossy(&text)
        );
        if new.is_ok() { ok += 1 } else { errors += 1 }
    }
    // Both outcomes are well represented.
    assert!(ok > 1000 && errors > 1000, "{ok} {errors}");
}

#[test]
fn line_counts_as_before() {
    let mut r = Rng::new(99);
    for _ in 0..5000 {
        let text = obj_text(&mut r);
        let old = (
            text.split(|&b| b == b'\n')
                .filter(|l| is_vertex_line(l))
                .count(),
            text.iter().filter(|&&b| b == b'\n').count(),
        );
        let n = count_lines(&text, false);
        assert_eq!(
            (n.vertices, n.newlines),
            old,
            "{:?}",
            String::from_utf8_lossy(&text)
        );
        let continued =
            text.windows(2).any(|w| w == b"\\\n") || text.windows(3).any(|w| w == b"\\\r\n");
        assert_eq!(has_continued_lines(&text), continued);
    }
    assert!(has_continued_lines(b"v 1 \\\r\n2 3\n"));
    assert!(!has_continued_lines(b"# a \\ b\n"));
}

/// Positive indices count from the file's first vertex (1-based), negative ones back from the
/// vertices defined before the line; zero, and anything before the first vertex or past the
/// count (when known) or a `u32` (when not), is out of range with a message saying which.
#[test]
fn indices_resolve() {
    assert_eq!(resolve_index(1, 5, None), Ok(0));
    assert_eq!(resolve_index(5, 5, Some(5)), Ok(4));
    assert_eq!(resolve_index(-1, 5, Some(5)), Ok(4));
    assert_eq!(resolve_index(-5, 5, None), Ok(0));
    // A forward reference is accepted while the count is unknown.
    assert_eq!(resolve_index(9, 5, None), Ok(8));
    assert_eq!(
        resolve_index(6, 5, Some(5)),
        Err("vertex index 6 is out of range (the file has 5 vertices)".into())
    );
    assert_eq!(
        resolve_index(-6, 5, None),
        Err("vertex index -6 is out of range (5 vertices are defined before this line)".into())
    );
    assert!(resolve_index(0, 5, Some(5)).is_err());
    assert!(resolve_index(1 << 33, 5, None).is_err());
    assert_eq!(resolve_index(1 << 32, 0, None), Ok(u32::MAX as usize));
}

/// A face corner's two indices read as a plain split at `/` and `str::parse` read them; the
/// vertex index as [`Line::index`] reads it.
#[test]
fn corners_read_as_std_reads_them() {
    let mut r = Rng::new(0xc0ffee);
    let pieces = [
        "1",
        "23",
        "-4",
        "+5",
        "",
        "x",
        "0",
        "99999999999999999999",
        "-",
        "7e1",
    ];
    for _ in 0..20_000 {
        let k = 1 + r.below(3);
        let tok: Vec<&str> = (0..k).map(|_| pieces[r.below(pieces.len())]).collect();
        let tok = tok.join("/");
        let text = format!(" {tok}  ");
        let mut parts = tok.split('/');
        let want = match parts.next().and_then(|v| v.parse::<i64>().ok()) {
            Some(v) => Some(Ok((v, parts.next().and_then(|t| t.parse::<i64>().ok())))),
            None if tok.is_empty() => None,
            None => Some(Err(tok.as_bytes())),
        };
        let mut l = line(text.as_bytes());
        assert_eq!(l.corner(), want, "{tok:?}");
        assert_eq!(l.corner(), None, "{tok:?}: one token");
        let mut l = line(text.as_bytes());
        assert_eq!(
            l.index().map(|r| r.ok()),
            want.map(|w| w.ok().map(|p| p.0)),
            "{tok:?}"
        );
    }
}
