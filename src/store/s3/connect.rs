//! Where the S3 store connects and how: `s3://BUCKET/PREFIX`, the client's configuration from
//! the `AWS_*` variables, bounded timeouts and retries.

use std::time::Duration;

use object_store::aws::{AmazonS3Builder, AmazonS3ConfigKey};
use object_store::{BackoffConfig, ClientConfigKey, RetryConfig};

/// `s3://BUCKET/PREFIX`: a bucket and a prefix (no leading or trailing `/`; may be empty).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Location {
    pub bucket: String,
    pub prefix: String,
}

impl Location {
    /// Parses what follows `s3://`.
    pub fn parse(rest: &str) -> Result<Location, String> {
        let (bucket, prefix) = rest.split_once('/').unwrap_or((rest, ""));
        // S3's bucket rules (3–63 of lowercase letters, digits, dots and hyphens), loosely:
        // S3-compatible servers accept a little more, and the server has the last word.
        if bucket.is_empty()
            || bucket.len() > 63
            || !bucket
                .bytes()
                .all(|b| b.is_ascii_alphanumeric() || b"-._".contains(&b))
        {
            return Err(format!(
                "s3://{rest}: {bucket:?} is not a bucket name; expected s3://BUCKET/PREFIX"
            ));
        }
        let prefix = prefix.trim_matches('/');
        if prefix.split('/').any(|p| p == "." || p == "..")
            || (!prefix.is_empty() && prefix.split('/').any(str::is_empty))
        {
            return Err(format!(
                "s3://{rest}: the prefix {prefix:?} is not a clean path"
            ));
        }
        Ok(Location {
            bucket: bucket.to_string(),
            prefix: prefix.to_string(),
        })
    }
}

impl std::fmt::Display for Location {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "s3://{}/{}", self.bucket, self.prefix)
    }
}

/// Bounded retries: an unreachable store fails a request within seconds, not minutes (the
/// crate's default is 10 retries over up to 3 minutes).
pub fn retry_config() -> RetryConfig {
    RetryConfig {
        backoff: BackoffConfig {
            init_backoff: Duration::from_millis(100),
            max_backoff: Duration::from_secs(2),
            base: 2.0,
        },
        max_retries: 3,
        retry_timeout: Duration::from_secs(15),
    }
}

/// The endpoint among `vars`: `AWS_ENDPOINT_URL_S3`, `AWS_ENDPOINT_URL` or `AWS_ENDPOINT`, the
/// first set wins (`object_store` reads the last two as one key, in whatever order they come).
pub(super) fn endpoint_of(vars: &[(String, String)]) -> Option<String> {
    ["AWS_ENDPOINT_URL_S3", "AWS_ENDPOINT_URL", "AWS_ENDPOINT"]
        .iter()
        .find_map(|k| {
            vars.iter()
                .find(|(name, v)| name == k && !v.trim().is_empty())
                .map(|(_, v)| v.trim().to_string())
        })
}

/// A client builder configured as `AmazonS3Builder::from_env` would be from `vars` (every
/// `AWS_*` key the crate knows: AWS_ACCESS_KEY_ID, AWS_SECRET_ACCESS_KEY, AWS_SESSION_TOKEN,
/// AWS_REGION or AWS_DEFAULT_REGION, AWS_ALLOW_HTTP, …), plus the endpoint rule above,
/// path-style requests for a custom endpoint, bounded retries and a connect timeout.
pub(super) fn builder(
    loc: &Location,
    vars: &[(String, String)],
    endpoint: Option<&str>,
) -> AmazonS3Builder {
    let mut b = AmazonS3Builder::new();
    for (k, v) in vars {
        if let Some(key) = k
            .strip_prefix("AWS_")
            .and_then(|_| k.to_ascii_lowercase().parse::<AmazonS3ConfigKey>().ok())
        {
            b = b.with_config(key, v);
        }
    }
    let mut b = b
        .with_bucket_name(&loc.bucket)
        .with_retry(retry_config())
        .with_config(
            AmazonS3ConfigKey::Client(ClientConfigKey::ConnectTimeout),
            "5s",
        );
    if let Some(e) = endpoint {
        // A custom endpoint (MinIO, SeaweedFS, Ceph…) is addressed path-style
        // (ENDPOINT/BUCKET/KEY) unless AWS_VIRTUAL_HOSTED_STYLE_REQUEST says otherwise.
        b = b.with_endpoint(e);
        if !vars
            .iter()
            .any(|(k, _)| k == "AWS_VIRTUAL_HOSTED_STYLE_REQUEST")
        {
            b = b.with_virtual_hosted_style_request(false);
        }
    }
    b
}

/// A random name for this process's probe object: 16 hex digits of 8 bytes from the operating
/// system's random source.
pub(super) fn instance_name() -> String {
    crate::app::store::random_hex::<8>()
}
