//! Talking to a running `voxd serve`: starting one and reading its address, one HTTP/1.1
//! exchange over a plain socket (no client library, so a torn or malformed response is seen as
//! it is), the response with its assertions, and a downloaded volume decoded. Not the servers
//! the tests start beside voxd (`nginx`, `redis_server`, `s3`).

use voxd::codec::VolumeFormat;
use voxd::volume::{BitVolume, Volume};

/// One HTTP/1.1 exchange over a fresh connection (`Connection: close`): the status, the headers
/// (names lowercased) and the body (chunked or not). Any failure, such as a server killed
/// mid-way, is an error, never a panic.
pub fn http_exchange(
    addr: &str,
    method: &str,
    path: &str,
    headers: &[(&str, &str)],
    body: &[u8],
) -> std::io::Result<(u16, std::collections::BTreeMap<String, String>, Vec<u8>)> {
    use std::collections::BTreeMap;
    use std::io::{Read, Write};
    let bad = |m: &str| std::io::Error::new(std::io::ErrorKind::InvalidData, m.to_string());
    let mut s = std::net::TcpStream::connect(addr)?;
    s.set_read_timeout(Some(std::time::Duration::from_secs(120)))?;
    s.set_write_timeout(Some(std::time::Duration::from_secs(120)))?;
    let mut head = format!(
        "{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\nContent-Length: {}\r\n",
        body.len()
    );
    for (k, v) in headers {
        head += &format!("{k}: {v}\r\n");
    }
    head += "\r\n";
    s.write_all(head.as_bytes())?;
    s.write_all(body)?;
    let mut raw = Vec::new();
    s.read_to_end(&mut raw)?;
    let split = raw
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .ok_or_else(|| bad("no response head"))?;
    let head = String::from_utf8_lossy(&raw[..split]).to_string();
    let mut lines = head.split("\r\n");
    let status = lines
        .next()
        .and_then(|l| l.split(' ').nth(1))
        .and_then(|s| s.parse().ok())
        .ok_or_else(|| bad("no status"))?;
    let headers: BTreeMap<String, String> = lines
        .filter_map(|l| l.split_once(':'))
        .map(|(k, v)| (k.trim().to_ascii_lowercase(), v.trim().to_string()))
        .collect();
    let mut body = raw[split + 4..].to_vec();
    if headers
        .get("transfer-encoding")
        .is_some_and(|t| t == "chunked")
    {
        let mut out = Vec::new();
        let mut rest = &body[..];
        loop {
            let eol = rest
                .windows(2)
                .position(|w| w == b"\r\n")
                .ok_or_else(|| bad("torn chunk"))?;
            let n = std::str::from_utf8(&rest[..eol])
                .ok()
                .and_then(|n| usize::from_str_radix(n.trim(), 16).ok())
                .ok_or_else(|| bad("bad chunk size"))?;
            if n == 0 {
                break;
            }
            let chunk = rest
                .get(eol + 2..eol + 2 + n)
                .ok_or_else(|| bad("torn chunk"))?;
            out.extend_from_slice(chunk);
            rest = rest.get(eol + 4 + n..).ok_or_else(|| bad("torn chunk"))?;
        }
        body = out;
    } else if headers
        .get("content-length")
        .and_then(|n| n.parse::<usize>().ok())
        .is_some_and(|n| n != body.len())
    {
        return Err(bad("torn body"));
    }
    Ok((status, headers, body))
}

/// A response, as [`http_exchange`] reads it.
#[derive(Debug)]
pub struct Resp {
    pub status: u16,
    pub headers: std::collections::BTreeMap<String, String>,
    pub body: Vec<u8>,
}

impl Resp {
    /// The body as JSON (a panic showing the body when it is not).
    pub fn json(&self) -> serde_json::Value {
        serde_json::from_slice(&self.body)
            .unwrap_or_else(|e| panic!("{e}: {}", String::from_utf8_lossy(&self.body)))
    }
    /// The body as JSON, or `None` when it is not.
    pub fn try_json(&self) -> Option<serde_json::Value> {
        serde_json::from_slice(&self.body).ok()
    }
    pub fn header(&self, h: &str) -> Option<&str> {
        self.headers.get(h).map(String::as_str)
    }
    /// Itself, once its status is `status`.
    pub fn ok(self, status: u16) -> Resp {
        assert_eq!(
            self.status,
            status,
            "{}",
            String::from_utf8_lossy(&self.body)
        );
        self
    }
    /// The problem document, once it is one of `slug` with `status`.
    pub fn problem(&self, status: u16, slug: &str) -> serde_json::Value {
        assert_eq!(
            self.status,
            status,
            "{}",
            String::from_utf8_lossy(&self.body)
        );
        assert_eq!(
            self.header("content-type"),
            Some("application/problem+json")
        );
        let p = self.json();
        assert_eq!(
            p["type"],
            format!("https://voxd.dev/problems/{slug}"),
            "{p}"
        );
        p
    }
}

/// Spawns `cmd` (a `voxd serve`; its stdout is piped here) and waits, 120 s at most, for its
/// `voxd listening on` line: the child and the address it listens on.
pub fn spawn_serve(cmd: &mut std::process::Command) -> (std::process::Child, String) {
    use std::io::BufRead;
    let mut child = cmd
        .stdout(std::process::Stdio::piped())
        .spawn()
        .expect("voxd starts");
    let stdout = child.stdout.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut line = String::new();
        let _ = std::io::BufReader::new(stdout).read_line(&mut line);
        let _ = tx.send(line);
    });
    let line = rx
        .recv_timeout(std::time::Duration::from_secs(120))
        .expect("voxd listens within 120 s");
    let addr = line
        .trim()
        .strip_prefix("voxd listening on http://")
        .unwrap_or_else(|| panic!("voxd did not start: {line:?}"))
        .to_string();
    (child, addr)
}

/// One exchange with `addr` as a [`Resp`]; a failed exchange is a panic naming the request.
pub fn request(
    addr: &str,
    method: &str,
    path: &str,
    headers: &[(&str, &str)],
    body: &[u8],
) -> Resp {
    try_request(addr, method, path, headers, body)
        .unwrap_or_else(|e| panic!("{method} {path} via {addr}: {e}"))
}

/// One exchange with `addr` as a [`Resp`], a failed one (a server killed mid-way) an error:
/// for the tests that kill servers on purpose.
pub fn try_request(
    addr: &str,
    method: &str,
    path: &str,
    headers: &[(&str, &str)],
    body: &[u8],
) -> std::io::Result<Resp> {
    let (status, headers, body) = http_exchange(addr, method, path, headers, body)?;
    Ok(Resp {
        status,
        headers,
        body,
    })
}

/// A downloaded volume file (any format, sniffed) as the bit volume it holds; a density volume
/// is a panic.
pub fn decode_bits(bytes: &[u8]) -> BitVolume {
    match VolumeFormat::sniff(bytes).unwrap().decode(bytes).unwrap() {
        Volume::Bits(b) => b,
        _ => panic!("not a bit volume"),
    }
}
