//! Numbers as people write them on a command line and read them in a report: counts such as
//! `5M` or `2.5e6`, lists of coordinates, and counts with thousands separators; bytes as hex.

/// Parses counts such as 1000, 1e6, 2.5M, 100k, 2G.
pub fn parse_count(s: &str) -> Result<u64, String> {
    let t = s.trim().replace('_', "");
    let (num, mult) = match t.chars().last() {
        Some('k' | 'K') => (&t[..t.len() - 1], 1e3),
        Some('m' | 'M') => (&t[..t.len() - 1], 1e6),
        Some('g' | 'G' | 'b' | 'B') => (&t[..t.len() - 1], 1e9),
        _ => (&t[..], 1.0),
    };
    if let Ok(n) = num.parse::<u64>() {
        return n
            .checked_mul(mult as u64)
            .ok_or_else(|| format!("{s} is too large"));
    }
    match num.parse::<f64>() {
        Ok(v) if v >= 0.0 && (v * mult).fract() == 0.0 && v * mult < 1.8e19 => {
            Ok((v * mult) as u64)
        }
        _ => Err(format!("\"{s}\" is not a whole number of points")),
    }
}

/// `n` with a comma between each group of three digits: 7,213,406.
pub fn thousands(n: u64) -> String {
    let s = n.to_string();
    let mut out = String::new();
    for (k, c) in s.chars().enumerate() {
        if k > 0 && (s.len() - k).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// `N` comma-separated finite numbers, such as a camera's `EX,EY,EZ,TX,TY,TZ` (NaN, inf and
/// numbers beyond f64's range, such as 1e400, are refused).
pub fn parse_floats<const N: usize>(s: &str) -> Result<[f64; N], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>().ok().filter(|x| x.is_finite()))
        .collect::<Option<_>>()
        .ok_or_else(|| format!("\"{s}\": expected {N} comma-separated finite numbers"))?;
    v.try_into()
        .map_err(|v: Vec<f64>| format!("\"{s}\": expected {N} numbers, got {}", v.len()))
}

/// Bytes as lower-case hex.
pub fn hex(b: &[u8]) -> String {
    b.iter().map(|v| format!("{v:02x}")).collect()
}

/// Hex back to bytes; `None` where it is not hex of whole bytes.
pub fn unhex(s: &str) -> Option<Vec<u8>> {
    if !s.len().is_multiple_of(2) {
        return None;
    }
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(s.get(i..i + 2)?, 16).ok())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex_both_ways() {
        assert_eq!(hex(&[0, 0xab, 0x10]), "00ab10");
        assert_eq!(unhex("00ab10"), Some(vec![0, 0xab, 0x10]));
        assert_eq!(unhex("0ab"), None);
        assert_eq!(unhex("zz"), None);
    }

    #[test]
    fn counts() {
        let check = |s: &str, v: Option<u64>| assert_eq!(parse_count(s).ok(), v, "{s}");
        check("1000", Some(1000));
        check("1e6", Some(1_000_000));
        check("2.5M", Some(2_500_000));
        check("100k", Some(100_000));
        check("2G", Some(2_000_000_000));
        check("1.5", None);
        check("abc", None);
        check("-5", None);
    }

    #[test]
    fn separators_and_lists() {
        assert_eq!(thousands(7213406), "7,213,406");
        assert_eq!(thousands(999), "999");
        assert_eq!(parse_floats::<3>("1, -2.5,3"), Ok([1.0, -2.5, 3.0]));
        assert!(parse_floats::<3>("1,2").is_err());
        // One NaN or infinity would be saved as JSON's null and make the work unreadable.
        for bad in ["NaN,1,2", "1,inf,2", "1,2,-inf", "1e400,1,2"] {
            assert!(parse_floats::<3>(bad).is_err(), "{bad}");
        }
    }
}
