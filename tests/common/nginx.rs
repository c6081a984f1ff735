//! A real nginx (Debian's package) as the load balancer in front of replicas, as the deployment
//! has it: round robin over the given upstreams on a free 127.0.0.1 port, its configuration,
//! logs and temporary files in a scratch directory, stopped on drop. A failed upstream is
//! skipped for idempotent requests (`proxy_next_upstream`). Absent binary: `None` with a notice,
//! unless `VOXD_REQUIRE_NGINX=1` (scripts/test.sh sets it once it has installed nginx).

use std::os::unix::process::CommandExt;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

pub struct Nginx {
    child: Child,
    pub addr: String,
    pub dir: PathBuf,
}

fn binary() -> Option<&'static str> {
    ["nginx", "/usr/sbin/nginx"].into_iter().find(|b| {
        Command::new(b)
            .arg("-v")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success())
    })
}

impl Nginx {
    /// nginx balancing over `upstreams` (`host:port` each); `None` (with a notice) when nginx
    /// is not installed, a failure when `VOXD_REQUIRE_NGINX=1`.
    pub fn start(name: &str, upstreams: &[&str]) -> Option<Nginx> {
        let Some(bin) = binary() else {
            assert!(
                std::env::var("VOXD_REQUIRE_NGINX").as_deref() != Ok("1"),
                "VOXD_REQUIRE_NGINX=1 but nginx is not installed (apt-get install nginx-light)"
            );
            eprintln!("NOTICE: nginx is not installed; skipping the load-balancer test {name}");
            return None;
        };
        let dir = super::tmpdir(&format!("nginx-{name}"));
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let servers: String = upstreams
            .iter()
            .map(|u| format!("    server {u} max_fails=1 fail_timeout=10s;\n"))
            .collect();
        let d = dir.display();
        let conf = format!(
            "worker_processes 1;\npid {d}/nginx.pid;\nerror_log {d}/error.log warn;\n\
             events {{ worker_connections 256; }}\n\
             http {{\n  access_log off;\n  client_body_temp_path {d}/body;\n  proxy_temp_path {d}/proxy;\n\
             \x20 fastcgi_temp_path {d}/fcgi;\n  uwsgi_temp_path {d}/uwsgi;\n  scgi_temp_path {d}/scgi;\n\
             \x20 client_max_body_size 256m;\n  upstream voxd {{\n{servers}  }}\n\
             \x20 server {{\n    listen 127.0.0.1:{port};\n    location / {{\n\
             \x20     proxy_pass http://voxd;\n      proxy_http_version 1.1;\n\
             \x20     proxy_set_header Connection \"\";\n      proxy_set_header X-Forwarded-For $remote_addr;\n\
             \x20     proxy_next_upstream error timeout http_502 http_503;\n\
             \x20     proxy_connect_timeout 2s;\n      proxy_read_timeout 300s;\n    }}\n  }}\n}}\n"
        );
        std::fs::write(dir.join("nginx.conf"), conf).unwrap();
        let child = Command::new(bin)
            .args(["-p", &dir.to_string_lossy(), "-c"])
            .arg(dir.join("nginx.conf"))
            .args(["-g", "daemon off;"])
            // A group of its own, so that Drop stops the workers with the master: a killed
            // master leaves its workers running (they were left behind before this).
            .process_group(0)
            .stdout(Stdio::null())
            .stderr(Stdio::inherit())
            .spawn()
            .unwrap();
        // Owned from here on, so that a failure below stops it too (Drop).
        let mut nginx = Nginx {
            child,
            addr: format!("127.0.0.1:{port}"),
            dir,
        };
        let deadline = Instant::now() + Duration::from_secs(30);
        while std::net::TcpStream::connect(&nginx.addr).is_err() {
            if let Some(s) = nginx.child.try_wait().unwrap() {
                panic!(
                    "nginx exited ({s}): {}",
                    std::fs::read_to_string(nginx.dir.join("error.log")).unwrap_or_default()
                );
            }
            assert!(
                Instant::now() < deadline,
                "nginx did not listen within 30 s"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        Some(nginx)
    }
}

/// `kill -SIG -- -GROUP` (the whole process group); does a process of the group exist?
fn signal_group(sig: &str, group: u32) -> bool {
    Command::new("kill")
        .args([sig, "--", &format!("-{group}")])
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

impl Drop for Nginx {
    fn drop(&mut self) {
        // nginx's graceful stop (SIGQUIT, the image's STOPSIGNAL, as deploy/local.sh sends):
        // the master tells its workers to finish, waits for them and exits.
        let group = self.child.id(); // the group's id is the master's
        let _ = Command::new("kill")
            .args(["-QUIT", &group.to_string()])
            .status();
        let deadline = Instant::now() + Duration::from_secs(10);
        while Instant::now() < deadline && !matches!(self.child.try_wait(), Ok(Some(_))) {
            std::thread::sleep(Duration::from_millis(20));
        }
        // Whatever is left of the group (a master that did not stop, a worker it did not wait
        // for), SIGKILLed, and waited for until no process of the group exists.
        let _ = signal_group("-KILL", group);
        let _ = self.child.kill();
        let _ = self.child.wait();
        let deadline = Instant::now() + Duration::from_secs(5);
        while signal_group("-0", group) && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}
