//! The standard `process_*` metrics (as Prometheus' client libraries name them), read from
//! `/proc/self` on each scrape: resident and virtual memory, CPU seconds, open file descriptors,
//! start time, threads (elsewhere than Linux, none of these); and the allowed file descriptors,
//! the soft limit the server's connection cap is derived from (`server::fd_limit`).

use std::fmt::Write;

/// Writes the process metrics to `s` (those that could be read).
pub fn render(s: &mut String) {
    for (name, kind, help, v) in read() {
        let _ = writeln!(s, "# HELP {name} {help}\n# TYPE {name} {kind}\n{name} {v}");
    }
}

/// `(name, type, help, value)` of every process metric that could be read.
fn read() -> Vec<(&'static str, &'static str, &'static str, f64)> {
    let mut out = Vec::new();
    // SAFETY: sysconf only reads configuration values.
    let (page, tick) = unsafe {
        (
            libc::sysconf(libc::_SC_PAGESIZE),
            libc::sysconf(libc::_SC_CLK_TCK),
        )
    };
    let (page, tick) = (page.max(1) as f64, tick.max(1) as f64);
    if let Some(stat) = self_stat() {
        // The fields after the command's closing parenthesis, from field 3 (state) on.
        let f: Vec<&str> = stat.split_whitespace().collect();
        let field = |n: usize| f.get(n - 3).and_then(|v| v.parse::<f64>().ok());
        if let (Some(utime), Some(stime)) = (field(14), field(15)) {
            out.push((
                "process_cpu_seconds_total",
                "counter",
                "Total user and system CPU time spent in seconds.",
                (utime + stime) / tick,
            ));
        }
        if let Some(threads) = field(20) {
            out.push((
                "process_threads",
                "gauge",
                "Number of OS threads in the process.",
                threads,
            ));
        }
        if let (Some(start), Some(boot)) = (field(22), boot_time()) {
            out.push((
                "process_start_time_seconds",
                "gauge",
                "Start time of the process since unix epoch in seconds.",
                boot + start / tick,
            ));
        }
        if let Some(vsize) = field(23) {
            out.push((
                "process_virtual_memory_bytes",
                "gauge",
                "Virtual memory size in bytes.",
                vsize,
            ));
        }
        if let Some(rss) = field(24) {
            out.push((
                "process_resident_memory_bytes",
                "gauge",
                "Resident memory size in bytes.",
                rss * page,
            ));
        }
    }
    if let Ok(fds) = std::fs::read_dir("/proc/self/fd") {
        out.push((
            "process_open_fds",
            "gauge",
            "Number of open file descriptors.",
            fds.count() as f64,
        ));
    }
    if let Some(max) = super::server::fd_limit() {
        out.push((
            "process_max_fds",
            "gauge",
            "Maximum number of open file descriptors.",
            max as f64,
        ));
    }
    out
}

/// `/proc/self/stat` after the command name (which may hold spaces and parentheses).
fn self_stat() -> Option<String> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    let end = stat.rfind(')')?;
    Some(stat[end + 1..].to_string())
}

/// Seconds since the epoch at boot (`btime` of `/proc/stat`).
fn boot_time() -> Option<f64> {
    std::fs::read_to_string("/proc/stat")
        .ok()?
        .lines()
        .find_map(|l| l.strip_prefix("btime ")?.trim().parse().ok())
}

#[cfg(test)]
mod tests {
    /// On Linux every metric is read, with values that make sense.
    #[test]
    #[cfg(target_os = "linux")]
    fn every_process_metric_is_read() {
        let got = super::read();
        let names: Vec<&str> = got.iter().map(|m| m.0).collect();
        for n in [
            "process_cpu_seconds_total",
            "process_start_time_seconds",
            "process_resident_memory_bytes",
            "process_virtual_memory_bytes",
            "process_open_fds",
            "process_max_fds",
            "process_threads",
        ] {
            assert!(names.contains(&n), "{n} missing from {names:?}");
        }
        let v = |n: &str| got.iter().find(|m| m.0 == n).unwrap().3;
        assert!(v("process_resident_memory_bytes") > 1e5);
        assert!(v("process_open_fds") >= 3.0);
        assert!(v("process_max_fds") >= v("process_open_fds"));
        // After 2020 and not in the future by more than a day.
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .as_secs_f64();
        let start = v("process_start_time_seconds");
        assert!(start > 1.5e9 && start < now + 86400.0, "{start}");
    }
}
