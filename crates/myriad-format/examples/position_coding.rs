//! Measures the position coding of a dataset's nodes: zigzag deltas in whole-byte planes (what
//! the format stores) against the same deltas bit-packed at the node's widest delta, both through
//! zstd level 3. `cargo run --release -p myriad-format --example position_coding DATASET.myr`
use myriad_format::Dataset;
fn main() {
    let path = std::env::args().nth(1).unwrap();
    let ds = Dataset::open(std::path::Path::new(&path)).unwrap();
    let q = ds.meta.quantization;
    let (nodes, _) = ds.nodes();
    let (mut planes_total, mut packed_total, mut n_total) = (0usize, 0usize, 0usize);
    for n in &nodes {
        let b = ds.read_node(n).unwrap();
        if b.is_empty() {
            continue;
        }
        let ints: Vec<[i64; 3]> = b.positions.iter().map(|&p| q.to_int(p)).collect();
        let mut planes = Vec::new();
        let mut bits_out: Vec<u8> = Vec::new();
        let (mut acc, mut nacc) = (0u128, 0u32);
        for a in 0..3 {
            let lo = ints.iter().map(|v| v[a]).min().unwrap();
            let hi = ints.iter().map(|v| v[a]).max().unwrap();
            let bits = 64 - ((hi - lo) as u64).leading_zeros();
            let w = (bits as usize).div_ceil(8);
            let mut prev = 0i64;
            let mut zz = Vec::new();
            for v in &ints {
                let rel = v[a] - lo;
                let d = rel - prev;
                prev = rel;
                zz.push(((d << 1) ^ (d >> 63)) as u64);
            }
            let zbits = zz.iter().map(|z| 64 - z.leading_zeros()).max().unwrap();
            // byte planes of zigzag in w bytes
            for k in 0..w {
                for z in &zz {
                    planes.push((z >> (8 * k)) as u8);
                }
            }
            for z in &zz {
                acc |= (*z as u128) << nacc;
                nacc += zbits;
                while nacc >= 8 {
                    bits_out.push(acc as u8);
                    acc >>= 8;
                    nacc -= 8;
                }
            }
        }
        if nacc > 0 {
            bits_out.push(acc as u8);
        }
        planes_total += zstd::bulk::compress(&planes, 3).unwrap().len();
        packed_total += zstd::bulk::compress(&bits_out, 3).unwrap().len();
        n_total += b.len();
    }
    println!(
        "byte planes: {:.3} B/pt, bit-packed: {:.3} B/pt",
        planes_total as f64 / n_total as f64,
        packed_total as f64 / n_total as f64
    );
}
