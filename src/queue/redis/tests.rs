//! The shared queue's pure parts: size classes, volume ids, redacted URLs, server versions
//! (what needs a Redis server is in tests/redis_queue.rs).

use super::*;

#[test]
fn classes_ids_urls_and_versions() {
    assert_eq!(class_of(64.0 * 64.0 * 64.0), "small");
    assert_eq!(class_of(256f64.powi(3)), "small");
    assert_eq!(class_of(300f64.powi(3)), "medium");
    assert_eq!(class_of(1024f64.powi(3)), "large");
    let v = volume_id_for("abc");
    assert_eq!((v.len(), v.clone()), (16, volume_id_for("abc")));
    assert_ne!(v, volume_id_for("abd"));
    assert!(v.bytes().all(|b| b.is_ascii_hexdigit()));
    assert_eq!(redact("redis://:s3cret@h:6379/2"), "redis://***@h:6379/2");
    assert_eq!(redact("redis://u:p@h"), "redis://***@h");
    assert_eq!(redact("redis://h:6379"), "redis://h:6379");
    assert_eq!(
        redis_version("# Server\r\nredis_version:7.0.15\r\n"),
        Some((7, 0))
    );
    assert_eq!(redis_version("redis_version:6.2.1"), Some((6, 2)));
    assert_eq!(redis_version("nothing"), None);
}
