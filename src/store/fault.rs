//! Fault injection for crash tests: with the `fault-injection` feature, `VOXD_FAULT=SPEC`
//! aborts the process (`std::process::abort`, as abrupt as SIGKILL) at one point of the
//! store's writes. `SPEC` is `abort-SITE` or `abort-SITE:N` (the N-th time this process reaches
//! that point, from 1; default 1), with `SITE` one of
//!
//! - `mid-data`: inside a put's `.vxl` write, half the bytes in the temporary file, not renamed
//!   (the S3 store: a data object of half the bytes);
//! - `after-data` (alias `before-commit`): a put's `.vxl` is written and in place, its metadata
//!   not;
//! - `after-commit`: both files durable, the catalogue and the caller not told;
//! - `mid-job-record`: inside an append to the job record log, its last line half written (the S3
//!   store: before the PUT, which is atomic).
//!
//! The S3 store (`super::s3`) stops at the same points.
//!
//! Without the feature every hook is an empty inline function and `VOXD_FAULT` is ignored.
//!
//! Its own module because every store writes through it (the directory store, its packs and
//! job log, the S3 store); it knows nothing of them.

use std::io::Write;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Site {
    MidData,
    AfterData,
    AfterCommit,
    MidJobRecord,
}

/// Writes `bytes` to `w` (a temporary file of an atomic write), aborting halfway when the
/// fault at `site` fires.
#[inline]
pub fn write(site: Site, w: &mut impl Write, bytes: &[u8]) -> std::io::Result<()> {
    #[cfg(feature = "fault-injection")]
    if armed::hit(site) {
        w.write_all(&bytes[..bytes.len() / 2])?;
        w.flush()?;
        abort(site);
    }
    let _ = site;
    w.write_all(bytes)
}

/// Aborts here when the fault at `site` fires.
#[inline]
pub fn point(site: Site) {
    #[cfg(feature = "fault-injection")]
    if armed::hit(site) {
        abort(site);
    }
    let _ = site;
}

/// Does the fault at `site` fire at this visit? For writes that tear themselves (an S3
/// put sends half its bytes), which then call [`abort`].
#[inline]
pub fn fires(site: Site) -> bool {
    #[cfg(feature = "fault-injection")]
    if armed::hit(site) {
        return true;
    }
    let _ = site;
    false
}

/// Aborts the process, saying where (after [`fires`]).
pub fn abort(site: Site) -> ! {
    eprintln!("voxd: fault injection: aborting at {site:?}");
    std::process::abort()
}

/// Parses a `VOXD_FAULT` value: the site and the hit that fires (from 1).
pub fn parse(spec: &str) -> Option<(Site, u64)> {
    let (name, n) = match spec.trim().split_once(':') {
        Some((name, n)) => (name, n.parse().ok().filter(|n| *n > 0)?),
        None => (spec.trim(), 1),
    };
    let site = match name.strip_prefix("abort-")? {
        "mid-data" => Site::MidData,
        "after-data" | "before-commit" => Site::AfterData,
        "after-commit" => Site::AfterCommit,
        "mid-job-record" => Site::MidJobRecord,
        _ => return None,
    };
    Some((site, n))
}

#[cfg(feature = "fault-injection")]
mod armed {
    use super::Site;
    use std::sync::OnceLock;
    use std::sync::atomic::{AtomicU64, Ordering};

    static FAULT: OnceLock<Option<(Site, u64)>> = OnceLock::new();
    static HITS: AtomicU64 = AtomicU64::new(0);

    /// Is this visit of `site` the one that fires?
    pub fn hit(site: Site) -> bool {
        let fault = FAULT.get_or_init(|| {
            let spec = std::env::var("VOXD_FAULT").ok()?;
            let f = super::parse(&spec);
            if f.is_none() {
                eprintln!("voxd: VOXD_FAULT={spec:?} is not a fault this build knows; ignored");
            }
            f
        });
        match *fault {
            Some((s, n)) if s == site => HITS.fetch_add(1, Ordering::SeqCst) + 1 == n,
            _ => false,
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn fault_specs_parse() {
        use super::{Site, parse};
        assert_eq!(parse("abort-before-commit"), Some((Site::AfterData, 1)));
        assert_eq!(parse("abort-after-data:3"), Some((Site::AfterData, 3)));
        assert_eq!(parse("abort-mid-data:2"), Some((Site::MidData, 2)));
        assert_eq!(parse("abort-after-commit"), Some((Site::AfterCommit, 1)));
        assert_eq!(
            parse("abort-mid-job-record:5"),
            Some((Site::MidJobRecord, 5))
        );
        for bad in [
            "",
            "abort",
            "abort-after-data:0",
            "abort-after-data:x",
            "after-data",
            "abort-elsewhere",
        ] {
            assert_eq!(parse(bad), None, "{bad}");
        }
    }
}
