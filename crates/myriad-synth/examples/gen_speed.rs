fn main() {
    let n: u64 = std::env::args()
        .nth(1)
        .map_or(5_000_000, |s| s.parse().unwrap());
    let t = std::time::Instant::now();
    let mut count = 0u64;
    let mut zmin = f64::MAX;
    let mut zmax = f64::MIN;
    let mut classes = [0u64; 32];
    myriad_synth::generate(
        &myriad_synth::SynthOptions {
            points: n,
            scene: myriad_synth::SceneKind::City,
            seed: 1,
        },
        |b| {
            count += b.len() as u64;
            for (p, c) in b.positions.iter().zip(b.classification.as_ref().unwrap()) {
                zmin = zmin.min(p[2]);
                zmax = zmax.max(p[2]);
                classes[*c as usize] += 1;
            }
            Ok(())
        },
    )
    .unwrap();
    let s = t.elapsed().as_secs_f64();
    println!(
        "{count} points in {s:.2} s: {:.2} M/s z {zmin}..{zmax} classes {:?}",
        count as f64 / s / 1e6,
        classes
    );
}
