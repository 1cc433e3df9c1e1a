//! The `Range` request header (RFC 9110 section 14): byte ranges only, each resolved against
//! the resource's length.

/// Most ranges served in one answer; a request for more is refused (RFC 9110 lets a server
/// reject many small ranges).
pub const MAX_RANGES: usize = 32;

/// What a `Range` header asks for.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Ranges {
    /// No byte ranges (no header, or a unit other than bytes): the whole resource.
    Whole,
    /// Inclusive first and last bytes, in the order asked, those past the end left out.
    Some(Vec<(u64, u64)>),
    /// Malformed, none satisfiable, or too many: 416.
    Unsatisfiable,
}

/// Parses a `Range` header value for a resource of `len` bytes.
pub fn parse(header: &str, len: u64) -> Ranges {
    let Some((unit, specs)) = header.split_once('=') else {
        return Ranges::Unsatisfiable;
    };
    if !unit.trim().eq_ignore_ascii_case("bytes") {
        return Ranges::Whole;
    }
    let mut out = Vec::new();
    let mut count = 0;
    for spec in specs.split(',') {
        let spec = spec.trim();
        if spec.is_empty() {
            continue;
        }
        count += 1;
        if count > MAX_RANGES {
            return Ranges::Unsatisfiable;
        }
        let Some((a, b)) = spec.split_once('-') else {
            return Ranges::Unsatisfiable;
        };
        let num = |s: &str| -> Option<u64> {
            (!s.is_empty() && s.bytes().all(|c| c.is_ascii_digit()))
                .then(|| s.parse().ok())
                .flatten()
        };
        match (a.trim(), b.trim()) {
            ("", suffix) => {
                let Some(n) = num(suffix) else {
                    return Ranges::Unsatisfiable;
                };
                if n > 0 && len > 0 {
                    out.push((len - n.min(len), len - 1));
                }
            }
            (first, "") => {
                let Some(first) = num(first) else {
                    return Ranges::Unsatisfiable;
                };
                if first < len {
                    out.push((first, len - 1));
                }
            }
            (first, last) => {
                let (Some(first), Some(last)) = (num(first), num(last)) else {
                    return Ranges::Unsatisfiable;
                };
                if first > last {
                    return Ranges::Unsatisfiable;
                }
                if first < len {
                    out.push((first, last.min(len - 1)));
                }
            }
        }
    }
    if out.is_empty() {
        Ranges::Unsatisfiable
    } else {
        Ranges::Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_as_rfc_9110_reads_them() {
        let some = |v: &[(u64, u64)]| Ranges::Some(v.to_vec());
        assert_eq!(parse("bytes=0-99", 1000), some(&[(0, 99)]));
        assert_eq!(parse("bytes=900-", 1000), some(&[(900, 999)]));
        assert_eq!(parse("bytes=-100", 1000), some(&[(900, 999)]));
        assert_eq!(parse("bytes=-5000", 1000), some(&[(0, 999)]));
        assert_eq!(parse("bytes=990-2000", 1000), some(&[(990, 999)]));
        assert_eq!(parse("BYTES = 0-0, 5-9", 1000), some(&[(0, 0), (5, 9)]));
        // Past the end: left out, or 416 when nothing is left.
        assert_eq!(parse("bytes=0-9,2000-3000", 1000), some(&[(0, 9)]));
        assert_eq!(parse("bytes=1000-", 1000), Ranges::Unsatisfiable);
        assert_eq!(parse("bytes=-0", 1000), Ranges::Unsatisfiable);
        // Malformed.
        for bad in [
            "bytes=",
            "bytes=a-b",
            "bytes=9-1",
            "bytes=--1",
            "bytes=1",
            "0-9",
            "bytes=+1-2",
        ] {
            assert_eq!(parse(bad, 1000), Ranges::Unsatisfiable, "{bad}");
        }
        // Another unit: ignored.
        assert_eq!(parse("items=0-9", 1000), Ranges::Whole);
        let many: Vec<String> = (0..=MAX_RANGES).map(|i| format!("{i}-{i}")).collect();
        assert_eq!(
            parse(&format!("bytes={}", many.join(",")), 1000),
            Ranges::Unsatisfiable
        );
    }
}
