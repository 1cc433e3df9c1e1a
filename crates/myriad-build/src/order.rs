//! The order a node's points are stored in within each level of detail: acquisition order (GPS
//! time), the last level dealt into strata spread over the node (`nodes::acquisition_order`
//! says why). Every builder orders a node this way before it gathers it.

use myriad_core::PointBatch;

/// `x.floor() as i64`, without the library call `floor` is on baseline x86-64.
fn floor_i64(x: f64) -> i64 {
    let t = x as i64;
    if (t as f64) > x {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// The order `nodes::acquisition_order` puts a node's `n` points in, as places `0..n`: the node's
/// i-th point is `source`'s `indices[i]` (its i-th without `indices`), levels by `prefix` and
/// `spacing`. A builder that gathers a node from a larger batch orders it this way first and
/// gathers once.
pub(crate) fn acquisition_permutation(
    source: &PointBatch,
    indices: Option<&[u32]>,
    n: usize,
    prefix: &[u64],
    spacing: &[f64],
) -> Vec<u32> {
    const STRATA: u32 = 4;
    let at = |i: usize| indices.map_or(i, |x| x[i] as usize);
    let times = source.gps_time.as_ref();
    // Sort keys; a time orders as `total_cmp` does; without times, the order the points have.
    let key = |i: usize| match times {
        Some(t) => {
            let b = t[at(i)].to_bits();
            b ^ (((b as i64) >> 63) as u64 | 1 << 63)
        }
        None => i as u64,
    };
    let last = prefix.len().saturating_sub(1);
    let mut order: Vec<u32> = Vec::with_capacity(n);
    let mut start = 0usize;
    for (level, &end) in prefix.iter().enumerate() {
        let end = (end as usize).min(n);
        // (key, point), sorted by key; the radix sort is stable and the points ascend, so
        // equal times keep the points' order.
        let mut keyed: Vec<(u64, u32)> = (start..end).map(|i| (key(i), i as u32)).collect();
        if times.is_some() {
            crate::radix::sort_by_key(&mut keyed, |k| k.0);
        }
        let cell = 2.0 * spacing.get(level).copied().unwrap_or(0.0);
        if level == last && cell > 0.0 && end - start > STRATA as usize {
            // Dealt into strata, each kept in acquisition order.
            let mut strata: Vec<Vec<u32>> = vec![Vec::new(); STRATA as usize];
            let mut seen: rustc_hash::FxHashMap<[i64; 3], u32> =
                rustc_hash::FxHashMap::with_capacity_and_hasher(end - start, Default::default());
            for k in &keyed {
                let p = source.positions[at(k.1 as usize)];
                let rank = seen.entry(p.map(|v| floor_i64(v / cell))).or_insert(0);
                strata[(*rank).min(STRATA - 1) as usize].push(k.1);
                *rank += 1;
            }
            strata.iter().for_each(|s| order.extend_from_slice(s));
        } else {
            order.extend(keyed.into_iter().map(|k| k.1));
        }
        start = end;
    }
    order
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_floor_matches_std() {
        for x in [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            -1.5,
            2.999,
            -2.999,
            1e300,
            -1e300,
            f64::NAN,
        ] {
            assert_eq!(floor_i64(x), x.floor() as i64, "{x}");
        }
    }
}
