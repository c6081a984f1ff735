//! API keys (`--api-keys-file FILE`): who may call the `/v1` routes, and how much.
//!
//! The file has one key per line, `NAME:SHA256-HEX`, optionally followed by that key's own
//! options, `NAME:SHA256-HEX:rate=R,burst=B,jobs=J,role=ROLE,tenant=T` (any subset; the limits
//! not given are the service's defaults, `--key-rate`, `--key-burst`, `--key-max-jobs`). Blank
//! lines and lines starting with `#` are ignored. Only digests are kept at rest; `voxd keygen
//! NAME` makes a key and its line.
//!
//! Tenants: every volume and job is owned by the tenant of the key that made it (`tenant=`,
//! the key's name by default; keys that name one tenant share its volumes and jobs). A key sees
//! its tenant's volumes and jobs only: any other is `404 not-found`, as if it did not exist, so
//! ids do not leak. Roles (`role=`): `user` (the default) reads and writes its tenant's;
//! `read-only` reads them, and every write (an upload, CSG, morphology, a delete, a cancel) is
//! `403 forbidden`; `admin` reads and writes every tenant's, and the volumes owned by none (made
//! without keys, or before volumes had owners).
//!
//! A request presents `Authorization: Bearer KEY`. The key's SHA-256 is compared with every
//! digest in the file, each comparison in constant time and all of them always made, so the
//! time taken says nothing about which digest (or how much of one) matched. The key itself is
//! never stored, logged or echoed; its name is what logs, job records and metrics show.
//!
//! Limits are per key and per replica: a rate (GCRA, `rate` requests per second with bursts of
//! `burst`), refused with `429 rate-limited` and the seconds until the next allowed request as
//! `Retry-After`; and at most `jobs` voxelization jobs queued or running at once (counted by the
//! queue, over all replicas when it is shared), refused with `429 too-many-jobs`.

use std::num::NonZeroU32;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

use axum::http::{HeaderMap, HeaderValue, header};
use governor::clock::{Clock, DefaultClock};
use governor::{DefaultDirectRateLimiter, Quota, RateLimiter};
use sha2::{Digest, Sha256};

use crate::app::queue::{Owner, Role};
use crate::app::{Error, ErrorKind};

/// A key's limits. `rate` 0: no rate limit; `max_jobs` 0: no job limit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KeyLimits {
    /// Requests per second, sustained.
    pub rate: u32,
    /// Requests at once above the sustained rate (at least 1 when `rate` is set).
    pub burst: u32,
    /// Voxelization jobs queued or running at once.
    pub max_jobs: usize,
}

impl KeyLimits {
    /// The service's defaults (`--key-rate`, `--key-burst`, `--key-max-jobs`).
    pub const DEFAULT: KeyLimits = KeyLimits {
        rate: 50,
        burst: 100,
        max_jobs: 16,
    };
}

struct Key {
    name: String,
    digest: [u8; 32],
    limits: KeyLimits,
    tenant: String,
    role: Role,
    limiter: Option<DefaultDirectRateLimiter>,
    requests: AtomicU64,
    limited: AtomicU64,
}

/// The keys of `--api-keys-file`.
pub struct ApiKeys {
    keys: Vec<Key>,
    /// `/metrics` needs a key too (`--protect-metrics`).
    pub protect_metrics: bool,
    unauthorized: AtomicU64,
    clock: DefaultClock,
}

/// A key name: what logs and records show, so plain: 1–64 of `A-Z a-z 0-9 . _ -`.
pub fn check_name(name: &str) -> Result<(), String> {
    let ok = !name.is_empty()
        && name.len() <= 64
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b"._-".contains(&b));
    if ok {
        Ok(())
    } else {
        Err(format!(
            "key name {name:?}: use 1 to 64 of the characters A-Z a-z 0-9 . _ -"
        ))
    }
}

/// A new key for `name`: the key (`voxd_` and 32 random bytes, base64url) and the keys file's
/// line for it.
pub fn generate(name: &str) -> Result<(String, String), String> {
    use base64::Engine as _;
    check_name(name)?;
    let mut bytes = [0u8; 32];
    getrandom::fill(&mut bytes).map_err(|e| format!("no random numbers from the system: {e}"))?;
    let key = format!(
        "voxd_{}",
        base64::engine::general_purpose::URL_SAFE_NO_PAD.encode(bytes)
    );
    let line = format!("{name}:{}", crate::app::store::sha256_hex(key.as_bytes()));
    Ok((key, line))
}

fn parse_hex32(s: &str) -> Option<[u8; 32]> {
    if s.len() != 64 || !s.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    let mut out = [0u8; 32];
    for (i, o) in out.iter_mut().enumerate() {
        *o = u8::from_str_radix(&s[2 * i..2 * i + 2], 16).ok()?;
    }
    Some(out)
}

/// A key line's options: its limits, role and tenant.
struct Options {
    limits: KeyLimits,
    role: Role,
    tenant: Option<String>,
}

fn parse_options(s: &str, defaults: KeyLimits) -> Result<Options, String> {
    let mut l = defaults;
    let (mut role, mut tenant) = (Role::User, None);
    for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let (k, v) = part
            .split_once('=')
            .ok_or_else(|| format!("{part:?} is not NAME=VALUE"))?;
        match k.trim() {
            "role" => {
                role = Role::parse(v.trim())
                    .ok_or_else(|| format!("role={v:?}: use user, read-only or admin"))?;
                continue;
            }
            "tenant" => {
                check_name(v.trim()).map_err(|e| format!("tenant: {e}"))?;
                tenant = Some(v.trim().to_string());
                continue;
            }
            _ => {}
        }
        let n: u64 = v
            .trim()
            .parse()
            .map_err(|_| format!("{k}={v:?} is not a whole number"))?;
        let n32 = u32::try_from(n).map_err(|_| format!("{k}={n} is too large"))?;
        match k.trim() {
            "rate" => l.rate = n32,
            "burst" => l.burst = n32,
            "jobs" => l.max_jobs = n32 as usize,
            other => {
                return Err(format!(
                    "unknown option {other:?} (rate, burst, jobs, role or tenant)"
                ));
            }
        }
    }
    Ok(Options {
        limits: l,
        role,
        tenant,
    })
}

impl ApiKeys {
    /// The keys of a keys file's text; errors name the line (never its digest).
    pub fn parse(text: &str, defaults: KeyLimits) -> Result<ApiKeys, String> {
        let mut keys: Vec<Key> = Vec::new();
        for (i, raw) in text.lines().enumerate() {
            let line = raw.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let at = |e: String| format!("line {}: {e}", i + 1);
            let mut fields = line.splitn(3, ':');
            let name = fields.next().unwrap_or_default().trim();
            check_name(name).map_err(at)?;
            let digest = fields
                .next()
                .map(str::trim)
                .and_then(parse_hex32)
                .ok_or_else(|| {
                    at(format!(
                        "{name}: expected NAME:SHA256-HEX (64 hex digits; `voxd keygen {name}` prints such a line)"
                    ))
                })?;
            let Options {
                limits,
                role,
                tenant,
            } = match fields.next() {
                Some(l) => parse_options(l, defaults).map_err(|e| at(format!("{name}: {e}")))?,
                None => Options {
                    limits: defaults,
                    role: Role::User,
                    tenant: None,
                },
            };
            if keys.iter().any(|k| k.name == name) {
                return Err(at(format!("{name}: a second key of that name")));
            }
            if keys.iter().any(|k| k.digest == digest) {
                return Err(at(format!("{name}: the same key as another line")));
            }
            let limiter = NonZeroU32::new(limits.rate).map(|rate| {
                let burst = NonZeroU32::new(limits.burst.max(1)).expect("at least 1");
                RateLimiter::direct(Quota::per_second(rate).allow_burst(burst))
            });
            keys.push(Key {
                name: name.into(),
                digest,
                limits,
                tenant: tenant.unwrap_or_else(|| name.to_string()),
                role,
                limiter,
                requests: AtomicU64::new(0),
                limited: AtomicU64::new(0),
            });
        }
        if keys.is_empty() {
            return Err(
                "no keys in it: every /v1 request would be refused (add a line from `voxd keygen NAME`)"
                    .into(),
            );
        }
        Ok(ApiKeys {
            keys,
            protect_metrics: false,
            unauthorized: AtomicU64::new(0),
            clock: DefaultClock::default(),
        })
    }

    /// The keys of the file at `path`.
    pub fn load(path: &Path, defaults: KeyLimits) -> Result<ApiKeys, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        ApiKeys::parse(&text, defaults).map_err(|e| format!("{}: {e}", path.display()))
    }

    pub fn len(&self) -> usize {
        self.keys.len()
    }

    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }

    /// The key whose digest is `presented`'s, comparing with every key in constant time.
    fn find(&self, presented: &str) -> Option<&Key> {
        let digest: [u8; 32] = Sha256::digest(presented.as_bytes()).into();
        let mut found = None;
        for k in &self.keys {
            // No early exit, in a byte or over the keys: every digest is compared in full.
            let diff = k
                .digest
                .iter()
                .zip(&digest)
                .fold(0u8, |acc, (a, b)| acc | (a ^ b));
            if std::hint::black_box(diff) == 0 {
                found = Some(k);
            }
        }
        found
    }

    /// Whether `path` needs a key.
    pub fn guards(&self, path: &str) -> bool {
        path == "/v1" || path.starts_with("/v1/") || (self.protect_metrics && path == "/metrics")
    }

    /// The key a request with these headers was made with, as the owner of the jobs it
    /// submits (handlers see it as a request extension), or why it is refused:
    /// `401 unauthorized` (with the `WWW-Authenticate` challenge to send) or `429 rate-limited`.
    pub fn authenticate(&self, headers: &HeaderMap) -> Result<Owner, Refusal> {
        let unauthorized = |detail: &str, error: Option<&str>| {
            self.unauthorized.fetch_add(1, Ordering::Relaxed);
            let challenge = match error {
                Some(e) => format!("Bearer realm=\"voxd\", error=\"{e}\""),
                None => "Bearer realm=\"voxd\"".into(),
            };
            Refusal {
                error: Error::new(ErrorKind::Unauthorized, detail),
                challenge: Some(HeaderValue::from_str(&challenge).expect("ASCII")),
            }
        };
        let Some(value) = headers.get(header::AUTHORIZATION) else {
            return Err(unauthorized(
                "this route needs an API key: send `Authorization: Bearer KEY`",
                None,
            ));
        };
        let token = value.to_str().ok().and_then(|v| {
            let (scheme, token) = v.trim().split_once(' ')?;
            let token = token.trim();
            (scheme.eq_ignore_ascii_case("bearer") && !token.is_empty() && !token.contains(' '))
                .then_some(token)
        });
        let Some(token) = token else {
            return Err(unauthorized(
                "the Authorization header must be `Bearer KEY`",
                Some("invalid_request"),
            ));
        };
        let Some(key) = self.find(token) else {
            return Err(unauthorized(
                "the API key is not valid",
                Some("invalid_token"),
            ));
        };
        key.requests.fetch_add(1, Ordering::Relaxed);
        if let Some(limiter) = &key.limiter
            && let Err(not_until) = limiter.check()
        {
            key.limited.fetch_add(1, Ordering::Relaxed);
            let wait = not_until.wait_time_from(self.clock.now());
            let secs = wait.as_secs_f64().ceil().max(1.0) as u64;
            return Err(Refusal {
                error: Error::new(
                    ErrorKind::RateLimited,
                    format!(
                        "key {} may make {} requests per second (bursts of {}); retry in {secs} s",
                        key.name,
                        key.limits.rate,
                        key.limits.burst.max(1)
                    ),
                )
                .retry_after(secs),
                challenge: None,
            });
        }
        Ok(Owner {
            name: key.name.clone(),
            max_jobs: key.limits.max_jobs,
            tenant: key.tenant.clone(),
            role: key.role,
        })
    }

    /// The Prometheus lines for the keys: requests and rate-limited requests per key, and
    /// requests refused for want of a valid key.
    pub fn render_metrics(&self, s: &mut String) {
        use std::fmt::Write;
        let _ = writeln!(
            s,
            "# HELP voxd_key_requests_total Requests authenticated with each API key (this replica).\n# TYPE voxd_key_requests_total counter"
        );
        for k in &self.keys {
            let _ = writeln!(
                s,
                "voxd_key_requests_total{{key=\"{}\"}} {}",
                k.name,
                k.requests.load(Ordering::Relaxed)
            );
        }
        let _ = writeln!(
            s,
            "# HELP voxd_key_rate_limited_total Requests refused with 429 rate-limited, per API key (this replica).\n# TYPE voxd_key_rate_limited_total counter"
        );
        for k in &self.keys {
            let _ = writeln!(
                s,
                "voxd_key_rate_limited_total{{key=\"{}\"}} {}",
                k.name,
                k.limited.load(Ordering::Relaxed)
            );
        }
        let _ = writeln!(
            s,
            "# HELP voxd_unauthorized_total Requests refused with 401: no key, or not a valid one (this replica).\n# TYPE voxd_unauthorized_total counter\nvoxd_unauthorized_total {}",
            self.unauthorized.load(Ordering::Relaxed)
        );
    }
}

/// A request refused by [`ApiKeys::authenticate`].
#[derive(Debug)]
pub struct Refusal {
    pub error: Error,
    /// `WWW-Authenticate` for a 401.
    pub challenge: Option<HeaderValue>,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bearer(key: &str) -> HeaderMap {
        let mut h = HeaderMap::new();
        h.insert(
            header::AUTHORIZATION,
            HeaderValue::from_str(&format!("Bearer {key}")).unwrap(),
        );
        h
    }

    #[test]
    fn keygen_lines_authenticate_their_key_only() {
        let (ka, la) = generate("alpha").unwrap();
        let (kb, lb) = generate("beta-2").unwrap();
        assert!(ka.starts_with("voxd_") && ka.len() == 5 + 43, "{ka}");
        assert_ne!(ka, kb);
        // The line holds the digest, not the key.
        assert!(!la.contains(&ka[5..]) && la.starts_with("alpha:"));
        let keys = ApiKeys::parse(
            &format!("# team keys\n\n{la}\n  {lb}:jobs=2  \n"),
            KeyLimits::DEFAULT,
        )
        .unwrap();
        assert_eq!(keys.len(), 2);
        let a = keys.authenticate(&bearer(&ka)).unwrap();
        assert_eq!((&*a.name, a.max_jobs), ("alpha", 16));
        let b = keys.authenticate(&bearer(&kb)).unwrap();
        assert_eq!((&*b.name, b.max_jobs), ("beta-2", 2));
        // A key one character off, a prefix, the digest itself, the empty header: all refused.
        let mut off = ka.clone().into_bytes();
        let last = off.last_mut().unwrap();
        *last = if *last == b'A' { b'B' } else { b'A' };
        for wrong in [
            String::from_utf8(off).unwrap(),
            ka[..20].to_string(),
            la[6..].to_string(),
        ] {
            let r = keys.authenticate(&bearer(&wrong)).unwrap_err();
            assert_eq!(r.error.kind, ErrorKind::Unauthorized);
            assert!(
                r.challenge
                    .unwrap()
                    .to_str()
                    .unwrap()
                    .contains("invalid_token")
            );
            assert!(!r.error.detail.contains(&wrong));
        }
        let none = keys.authenticate(&HeaderMap::new()).unwrap_err();
        assert_eq!(none.challenge.unwrap(), "Bearer realm=\"voxd\"");
        let mut basic = HeaderMap::new();
        basic.insert(
            header::AUTHORIZATION,
            HeaderValue::from_static("Basic YTpi"),
        );
        let r = keys.authenticate(&basic).unwrap_err();
        assert!(
            r.challenge
                .unwrap()
                .to_str()
                .unwrap()
                .contains("invalid_request")
        );
        // Scheme names are case-insensitive.
        let mut lower = HeaderMap::new();
        lower.insert(
            header::AUTHORIZATION,
            HeaderValue::from_str(&format!("bearer {ka}")).unwrap(),
        );
        assert!(keys.authenticate(&lower).is_ok());
    }

    #[test]
    fn bad_files_are_refused_by_line_without_their_digests() {
        let (_, l) = generate("a").unwrap();
        let digest = &l[2..];
        for (text, says) in [
            ("", "no keys"),
            ("# only a comment\n", "no keys"),
            ("a:abc\n", "line 1"),
            (&format!("b c:{digest}\n"), "key name"),
            (&format!("a:{digest}\na:{}\n", "0".repeat(64)), "second key"),
            (&format!("a:{digest}\nb:{digest}\n"), "same key"),
            (&format!("\n\na:{digest}:rate=x\n"), "line 3"),
            (&format!("a:{digest}:speed=3\n"), "unknown option"),
            (&format!("a:{digest}:role=root\n"), "read-only or admin"),
            (&format!("a:{digest}:tenant=a/b\n"), "tenant"),
            (&format!("a:{digest}:rate=99999999999\n"), "too large"),
        ] {
            let e = ApiKeys::parse(text, KeyLimits::DEFAULT).err().unwrap();
            assert!(e.contains(says), "{text:?}: {e}");
            assert!(!e.contains(digest), "{e}");
        }
        assert!(generate("").is_err() && generate("a/b").is_err());
        assert!(generate(&"x".repeat(65)).is_err() && generate(&"x".repeat(64)).is_ok());
    }

    #[test]
    fn roles_and_tenants_come_from_the_keys_line() {
        let (ka, la) = generate("a").unwrap();
        let (kr, lr) = generate("r").unwrap();
        let (kx, lx) = generate("x").unwrap();
        let keys = ApiKeys::parse(
            &format!("{la}\n{lr}:role=read-only,tenant=a,jobs=2\n{lx}:role=admin\n"),
            KeyLimits::DEFAULT,
        )
        .unwrap();
        let owner = |k: &str| {
            let mut h = HeaderMap::new();
            let v = HeaderValue::from_str(&format!("Bearer {k}")).unwrap();
            h.insert(header::AUTHORIZATION, v);
            keys.authenticate(&h).unwrap()
        };
        let (a, r, x) = (owner(&ka), owner(&kr), owner(&kx));
        assert_eq!((a.tenant.as_str(), a.role), ("a", Role::User));
        assert_eq!(
            (r.tenant.as_str(), r.role, r.max_jobs),
            ("a", Role::ReadOnly, 2)
        );
        assert_eq!((x.tenant.as_str(), x.role), ("x", Role::Admin));
        // Its tenant's only; an admin every one's, and those owned by none.
        assert!(a.sees(Some("a")) && r.sees(Some("a")));
        assert!(!a.sees(Some("x")) && !a.sees(None) && !r.sees(Some("r")));
        assert!(x.sees(Some("a")) && x.sees(None));
    }

    #[test]
    fn rates_are_per_key_with_retry_after() {
        let (ka, la) = generate("slow").unwrap();
        let (kb, lb) = generate("free").unwrap();
        let keys = ApiKeys::parse(
            &format!("{la}:rate=1,burst=3\n{lb}:rate=0\n"),
            KeyLimits::DEFAULT,
        )
        .unwrap();
        // A burst of 3, then refusals (1 per second: the next one is within a second).
        for _ in 0..3 {
            keys.authenticate(&bearer(&ka)).unwrap();
        }
        let r = keys.authenticate(&bearer(&ka)).unwrap_err();
        assert_eq!(r.error.kind, ErrorKind::RateLimited);
        assert_eq!(r.error.retry_after, Some(1));
        assert!(r.challenge.is_none());
        // The other key is not held back by the first one's use, and rate=0 is no limit.
        for _ in 0..1000 {
            keys.authenticate(&bearer(&kb)).unwrap();
        }
        let mut m = String::new();
        keys.render_metrics(&mut m);
        assert!(m.contains("voxd_key_requests_total{key=\"slow\"} 4"), "{m}");
        assert!(
            m.contains("voxd_key_rate_limited_total{key=\"slow\"} 1"),
            "{m}"
        );
        assert!(
            m.contains("voxd_key_requests_total{key=\"free\"} 1000"),
            "{m}"
        );
        assert!(!m.contains(&ka) && !m.contains(&kb));
    }

    #[test]
    fn guarded_paths() {
        let (_, l) = generate("a").unwrap();
        let mut keys = ApiKeys::parse(&l, KeyLimits::DEFAULT).unwrap();
        for (p, g) in [
            ("/v1/voxelize", true),
            ("/v1/volumes", true),
            ("/v1", true),
            ("/v10", false),
            ("/healthz", false),
            ("/readyz", false),
            ("/metrics", false),
            ("/openapi.yaml", false),
        ] {
            assert_eq!(keys.guards(p), g, "{p}");
        }
        keys.protect_metrics = true;
        assert!(keys.guards("/metrics") && !keys.guards("/healthz"));
    }
}
