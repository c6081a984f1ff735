//! `Content-Disposition` of a download (RFC 6266): the volume's name as the file name, an
//! ASCII fallback in `filename` that every client reads, and the name as given, UTF-8 and
//! percent-encoded (RFC 8187), in `filename*` where the fallback had to change it. A volume
//! without a usable name (none, empty, or nothing left of it in ASCII) is named by its id.

/// The header value for a download of volume `id`, named `name`, as `.{ext}`.
pub fn attachment(name: Option<&str>, id: &str, ext: &str) -> String {
    let name = name.map(str::trim).filter(|n| !n.is_empty());
    let ascii = |s: &str| -> String {
        s.chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                    c
                } else {
                    '_'
                }
            })
            .collect()
    };
    let fallback = name
        .map(ascii)
        .filter(|f| f.chars().any(|c| c != '_'))
        .unwrap_or_else(|| ascii(id));
    let mut v = format!("attachment; filename=\"{fallback}.{ext}\"");
    if let Some(n) = name.filter(|n| *n != fallback) {
        v.push_str("; filename*=UTF-8''");
        for b in format!("{n}.{ext}").bytes() {
            let keep = b.is_ascii_alphanumeric() || b"!#$&+-.^_`|~".contains(&b);
            if keep {
                v.push(b as char);
            } else {
                v.push_str(&format!("%{b:02X}"));
            }
        }
    }
    v
}

#[cfg(test)]
mod tests {
    use super::attachment;

    #[test]
    fn names_ids_and_utf8() {
        assert_eq!(
            attachment(Some("bunny-64"), "ab12", "npy"),
            "attachment; filename=\"bunny-64.npy\""
        );
        // No name, an empty one, one of spaces: the id.
        for n in [None, Some(""), Some("  ")] {
            assert_eq!(
                attachment(n, "ab12", "vxl"),
                "attachment; filename=\"ab12.vxl\""
            );
        }
        // Changed for ASCII: the fallback, and the name as given in filename*.
        assert_eq!(
            attachment(Some("Würfel 1"), "ab12", "npy"),
            "attachment; filename=\"W_rfel_1.npy\"; filename*=UTF-8''W%C3%BCrfel%201.npy"
        );
        // Nothing left in ASCII: the id, and the name in filename*.
        assert_eq!(
            attachment(Some("立方体"), "ab12", "raw"),
            "attachment; filename=\"ab12.raw\"; filename*=UTF-8''%E7%AB%8B%E6%96%B9%E4%BD%93.raw"
        );
        // Quotes and backslashes never reach the quoted string.
        assert_eq!(
            attachment(Some("a\"b\\c"), "ab12", "npy"),
            "attachment; filename=\"a_b_c.npy\"; filename*=UTF-8''a%22b%5Cc.npy"
        );
    }
}
