//! A connection flood from one client (issue 30, defect 1), against the real server with a small
//! cap: one client holds more idle and half-sent sockets than the cap, and another client's
//! `/healthz` is still answered (the server closes the connection idle longest to make room);
//! with a per-client cap, the flooding address's extra connections are closed at once. The
//! flooding client connects from 127.0.0.2, the probing one from 127.0.0.1 (both loopback).
//! Every wait is bounded; nothing asserts a timing beyond "answered before a 10 s timeout".

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::Duration;

use crate::common::Scratch;
use crate::service::Server;

/// A socket to `addr` from 127.0.0.2 (another client address on loopback).
fn connect_from_other(addr: &str) -> TcpStream {
    let to: SocketAddr = addr.parse().unwrap();
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_io()
        .build()
        .unwrap();
    let s = rt.block_on(async {
        let s = tokio::net::TcpSocket::new_v4().unwrap();
        s.bind("127.0.0.2:0".parse().unwrap()).unwrap();
        s.connect(to).await.unwrap()
    });
    let s = s.into_std().unwrap();
    s.set_nonblocking(false).unwrap();
    s
}

/// `/healthz` from 127.0.0.1 with a 10 s read timeout: its status line, or why none came.
fn probe(addr: &str) -> Result<String, String> {
    let mut s = TcpStream::connect(addr).map_err(|e| e.to_string())?;
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    s.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")
        .map_err(|e| e.to_string())?;
    let mut got = vec![];
    s.read_to_end(&mut got)
        .map_err(|e| format!("no answer: {e}"))?;
    Ok(String::from_utf8_lossy(&got)
        .lines()
        .next()
        .unwrap_or("")
        .to_string())
}

/// 200 idle and half-sent sockets from one client against a cap of 64 (per-client cap off, a
/// 30 s header timeout so nothing times out on its own): another client is answered.
#[test]
fn a_flood_of_idle_connections_does_not_shut_out_another_client() {
    let dir = Scratch::new("flood-idle");
    let srv = Server::start(
        &dir,
        &[
            "--max-connections",
            "64",
            "--max-connections-per-client",
            "0",
            "--header-timeout",
            "30",
        ],
    );
    let mut held = vec![];
    for i in 0..200 {
        let mut s = connect_from_other(&srv.addr);
        if i % 2 == 1 {
            let _ = s.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\n");
        }
        held.push(s);
    }
    std::thread::sleep(Duration::from_millis(300));
    for _ in 0..3 {
        let line = probe(&srv.addr).expect("another client is answered");
        assert!(line.starts_with("HTTP/1.1 200"), "{line}");
    }
    drop(held);
}

/// With `--max-connections-per-client 8`, a client's ninth and later connections are closed at
/// once, its first eight stay open, and another address is answered.
#[test]
fn connections_over_the_per_client_cap_are_closed() {
    let dir = Scratch::new("flood-per-client");
    let srv = Server::start(
        &dir,
        &[
            "--max-connections-per-client",
            "8",
            "--header-timeout",
            "30",
        ],
    );
    let mut held: Vec<TcpStream> = (0..20).map(|_| connect_from_other(&srv.addr)).collect();
    std::thread::sleep(Duration::from_millis(500));
    let mut closed = 0;
    for s in &mut held {
        s.set_read_timeout(Some(Duration::from_millis(300)))
            .unwrap();
        let mut b = [0u8; 16];
        match s.read(&mut b) {
            Ok(0) => closed += 1,
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionReset => closed += 1,
            _ => {}
        }
    }
    assert_eq!(
        closed, 12,
        "of 20 connections from one address with a cap of 8"
    );
    let line = probe(&srv.addr).expect("another client is answered");
    assert!(line.starts_with("HTTP/1.1 200"), "{line}");
}
