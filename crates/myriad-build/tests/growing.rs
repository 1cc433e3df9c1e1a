//! A build drawn while it runs (`myriad_build::growing`): every snapshot opens as a dataset and
//! reads without damage, what is built grows from one to the next while the preview fills the
//! rest, and the finished dataset is the one `convert` writes without snapshots.

mod common;
use common::{synth, tempdir};

use myriad_build::convert::{ConvertOptions, Silent, convert};
use myriad_build::growing::Growing;
use myriad_format::Dataset;
use std::collections::BTreeMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// Every node's key, point count and page bytes.
fn pages(ds: &Dataset) -> BTreeMap<String, (u32, Vec<u8>)> {
    let (nodes, damage) = ds.nodes();
    assert!(damage.is_empty(), "{damage:?}");
    nodes
        .iter()
        .map(|e| (e.key.to_string(), (e.points, ds.node_page(e).unwrap())))
        .collect()
}

#[test]
fn snapshots_grow_and_the_dataset_is_convert_s() {
    let d = tempdir("growing");
    let las = synth(&d, 300_000, 11);
    let options = |out: &std::path::Path| {
        let mut o = ConvertOptions::new(out);
        o.open = myriad_io::OpenOptions::default();
        o.memory = myriad_build::convert::MIN_MEMORY;
        o.chunk_points = Some(20_000);
        o.params.capacity = 4096;
        o.threads = 2;
        o
    };
    let plain = d.join("plain.myr");
    convert(std::slice::from_ref(&las), &options(&plain), &Silent).unwrap();

    let grown = d.join("grown.myr");
    let g = Growing::new(Duration::ZERO);
    g.set_fill(myriad_build::cached::preview_batch(&las).unwrap());
    let mut o = options(&grown);
    o.growing = Some(g.clone());
    // Snapshots as the build makes them, looked at from another thread.
    let done = Arc::new(AtomicBool::new(false));
    let watcher = {
        let (g, done) = (g.clone(), done.clone());
        std::thread::spawn(move || {
            let mut seen = Vec::new();
            let mut last = 0;
            while !done.load(Ordering::Relaxed) {
                if let Some(s) = g.latest().filter(|s| s.version != last) {
                    last = s.version;
                    let prefix = s.bytes.prefix();
                    let (nodes, damage) = s.dataset.nodes();
                    assert!(damage.is_empty(), "snapshot {}: {damage:?}", s.version);
                    let (mut built, mut filled) = (0u64, 0u64);
                    for e in &nodes {
                        let b = s.dataset.read_node(e).unwrap();
                        assert_eq!(b.len(), e.points as usize);
                        if e.page.length > 0 && e.page.offset >= prefix {
                            filled += b.len() as u64;
                        } else {
                            built += b.len() as u64;
                        }
                    }
                    assert_eq!(s.dataset.meta.points, built + filled);
                    seen.push((s.built, s.chunks, built, filled));
                }
                std::thread::sleep(Duration::from_millis(2));
            }
            seen
        })
    };
    let summary = convert(std::slice::from_ref(&las), &o, &Silent).unwrap();
    done.store(true, Ordering::Relaxed);
    let seen = watcher.join().unwrap();
    eprintln!("snapshots looked at (chunks built, of, points built, preview points): {seen:?}");
    assert_eq!(summary.points, 300_000);
    assert!(summary.chunks >= 8, "{} chunks", summary.chunks);
    // Several snapshots were looked at; what is built only grows; the first still shows the
    // preview where chunks are missing; the last (made when every chunk was built) only in the
    // chunks whose points all wait in their roots (written with the levels above, at the end).
    // While the build reads, snapshots of the fill alone (the preview and a sample of what is
    // decoded, growing); then those of what is built.
    let reading = seen.iter().take_while(|s| s.1 == 0).count();
    assert!(reading >= 1, "{seen:?}");
    assert!(
        seen[..reading].windows(2).all(|w| w[1].3 >= w[0].3),
        "{seen:?}"
    );
    let seen = &seen[reading..];
    assert!(seen.len() >= 2, "{seen:?}");
    assert!(seen.iter().all(|s| s.1 > 0), "{seen:?}");
    assert!(
        seen.windows(2)
            .all(|w| w[1].0 >= w[0].0 && w[1].2 >= w[0].2),
        "{seen:?}"
    );
    let first = seen[0];
    assert!(first.0 < first.1 && first.3 > 0, "{seen:?}");
    let last = *seen.last().unwrap();
    assert_eq!(last.0, last.1, "{seen:?}");
    assert!(last.3 < first.3 / 2, "{seen:?}");
    assert!(last.2 > 0 && last.2 < 300_000, "{seen:?}");
    // The dataset is convert's: the same nodes with the same pages.
    let a = pages(&Dataset::open(&plain).unwrap());
    let b = pages(&Dataset::open(&grown).unwrap());
    assert_eq!(a.len(), b.len());
    assert!(a == b, "the nodes' pages differ");
}

#[test]
fn the_chunks_a_viewer_looks_at_are_built_first() {
    let d = tempdir("growing-focus");
    let las = synth(&d, 300_000, 12);
    let bounds = myriad_io::open(&las, &myriad_io::OpenOptions::default())
        .unwrap()
        .info()
        .bounds
        .unwrap();
    let out = d.join("focus.myr");
    let g = Growing::new(Duration::from_secs(3600));
    // A corner of the scan.
    let at = bounds.min;
    g.set_focus(Some(at));
    let mut o = ConvertOptions::new(&out);
    o.open = myriad_io::OpenOptions::default();
    o.memory = myriad_build::convert::MIN_MEMORY;
    o.chunk_points = Some(20_000);
    o.params.capacity = 4096;
    o.threads = 2;
    o.growing = Some(g.clone());
    convert(std::slice::from_ref(&las), &o, &Silent).unwrap();
    let root = Dataset::open(&out).unwrap().meta.root;
    let order = g.built_order();
    assert!(order.len() >= 8, "{} chunks", order.len());
    let far = |k: &myriad_core::NodeKey| {
        let c = k.bounds(&root);
        (0..3)
            .map(|a| (c.min[a] - at[a]).max(at[a] - c.max[a]).max(0.0).powi(2))
            .sum::<f64>()
    };
    // Ranks by distance: the two workers took the two nearest first, and the nearer half of
    // the chunks came before the farther half.
    let mut by_distance = order.clone();
    by_distance.sort_by(|a, b| far(a).total_cmp(&far(b)));
    let rank = |k: &myriad_core::NodeKey| by_distance.iter().position(|x| x == k).unwrap();
    assert!(rank(&order[0]) <= 1, "{order:?}");
    let half = order.len() / 2;
    let mean = |ks: &[myriad_core::NodeKey]| ks.iter().map(rank).sum::<usize>() / ks.len();
    assert!(
        mean(&order[..half]) < mean(&order[half..]),
        "ranks in build order: {:?}",
        order.iter().map(rank).collect::<Vec<_>>()
    );
    // Without a focus: the largest first, as convert always did.
    let g = Growing::new(Duration::from_secs(3600));
    o.growing = Some(g.clone());
    o.force = true;
    convert(std::slice::from_ref(&las), &o, &Silent).unwrap();
    assert_eq!(g.built_order().len(), order.len());
}
