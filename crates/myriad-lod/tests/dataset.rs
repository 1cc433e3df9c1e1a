//! Selection on a real converted dataset: the budget holds, prefixes are prefixes of the nodes,
//! and the framing view of the whole dataset draws the whole of it when the budget allows.

use myriad_build::convert::{ConvertOptions, Silent, convert};
use myriad_format::Dataset;
use myriad_lod::{Camera, Hierarchy, SelectOptions, select};

#[test]
fn select_on_a_converted_scan() {
    let d = std::env::temp_dir().join(format!("myriad-lod-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let las = d.join("city.las");
    let opts = myriad_synth::SynthOptions {
        points: 300_000,
        scene: myriad_synth::SceneKind::City,
        seed: 2,
    };
    myriad_synth::write(&opts, &las, true, |_| {}).unwrap();
    let out = d.join("city.myr");
    let mut o = ConvertOptions::new(&out);
    o.open = myriad_io::OpenOptions::default();
    o.params.capacity = 4096;
    convert(std::slice::from_ref(&las), &o, &Silent).unwrap();
    let ds = Dataset::open(&out).unwrap();
    let (nodes, damage) = ds.nodes();
    assert!(damage.is_empty());
    let h = Hierarchy::new(ds.meta.root, nodes);
    assert_eq!(h.points(), 300_000);
    let cam = Camera::framing(&ds.meta.bounds, 1280, 720, 60.0);
    for budget in [10_000u64, 100_000, 1_000_000] {
        let s = select(
            &h,
            &cam,
            &SelectOptions {
                budget,
                min_pixels: 0.0,
            },
        );
        assert!(s.points <= budget);
        for n in &s.nodes {
            let e = h.get(&n.key).unwrap();
            assert!(n.points <= e.points && n.points > 0);
            // A prefix ends on a level boundary unless the budget cut it.
            assert!(
                e.prefix.contains(&n.points) || (s.budget_reached && Some(n) == s.nodes.last())
            );
        }
        if budget >= 300_000 {
            assert_eq!(s.points, 300_000, "all of it fits and is in view");
        } else {
            assert!(s.budget_reached);
        }
    }
    // At a 1-pixel threshold a small framing view draws less than everything (far points are
    // dense).
    let small = Camera::framing(&ds.meta.bounds, 320, 180, 60.0);
    let s = select(
        &h,
        &small,
        &SelectOptions {
            budget: u64::MAX,
            min_pixels: 1.0,
        },
    );
    assert!(s.points > 10_000 && s.points < 300_000, "{}", s.points);

    // Streaming it: loader threads read the selected nodes from the file into the cache.
    let ds = std::sync::Arc::new(ds);
    let mut loader = myriad_lod::Loader::new(ds.clone(), 2, 1 << 30);
    let s = select(
        &h,
        &cam,
        &SelectOptions {
            budget: 100_000,
            min_pixels: 1.0,
        },
    );
    let wanted: Vec<_> = s
        .nodes
        .iter()
        .map(|n| h.get(&n.key).unwrap().clone())
        .collect();
    loader.request(&wanted);
    while loader.in_flight() > 0 {
        loader.poll();
        std::thread::yield_now();
    }
    let mut drawn = 0;
    for n in &s.nodes {
        let b = loader.get(&n.key).expect("resident");
        assert_eq!(b.len() as u32, h.get(&n.key).unwrap().points);
        drawn += n.points as u64;
    }
    assert_eq!(drawn, s.points);
    assert!(loader.failed().is_empty());
    std::fs::remove_dir_all(&d).ok();
}
