//! `convert` end to end: nothing lost (every field of every point survives convert then
//! extract), the dataset's invariants, box and spacing queries, damaged pages caught and named.

mod common;
use common::{read_all, records, synth, tempdir};

use myriad_build::convert::{ConvertOptions, Silent, Structure, convert};
use myriad_build::export::{ExportOptions, Target, export};
use myriad_build::extract::{ExtractOptions, extract, verify};
use myriad_core::{Aabb, PointBatch};
use myriad_format::Dataset;
use myriad_io::OpenOptions;
use std::path::{Path, PathBuf};

fn data_dir() -> Option<PathBuf> {
    let d = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    if d.is_dir() {
        Some(d)
    } else {
        use std::io::Write;
        let _ = writeln!(
            std::io::stderr(),
            "SKIPPED: {} not found; real-data tests need ../shared/data",
            d.display()
        );
        None
    }
}

fn options(out: &Path) -> ConvertOptions {
    let mut o = ConvertOptions::new(out);
    o.open = OpenOptions::default();
    o
}

#[test]
fn nothing_lost_many_chunks_and_nodes() {
    let d = tempdir("convert-synth");
    let las = synth(&d, 400_000, 5);
    let out = d.join("city.myr");
    let mut o = options(&out);
    // The smallest budget, and chunks of 30 000 points, so the build runs on many chunks and
    // merges them; small nodes, so the tree is deep.
    o.memory = myriad_build::convert::MIN_MEMORY;
    o.chunk_points = Some(30_000);
    o.params.capacity = 4096;
    o.threads = 2;
    let s = convert(std::slice::from_ref(&las), &o, &Silent).unwrap();
    assert_eq!(s.points, 400_000);
    assert!(s.chunks >= 8, "{} chunks", s.chunks);
    assert!(s.depth >= 4, "depth {}", s.depth);
    // The spill folder is gone; only the input and the dataset remain.
    let mut names: Vec<String> = std::fs::read_dir(&d)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    assert_eq!(names, ["city.las", "city.myr"]);

    let ds = Dataset::open(&out).unwrap();
    assert_eq!(ds.meta.points, 400_000);
    assert_eq!(ds.meta.nodes, s.nodes);
    let r = verify(&ds, |_| {});
    assert!(r.damage.is_empty(), "{:?}", r.damage);
    assert_eq!(r.points, 400_000);

    let back = d.join("back.las");
    let e = extract(&ds, &back, &ExtractOptions::default()).unwrap();
    assert_eq!(e.points, 400_000);
    assert_eq!(records(&read_all(&back)), records(&read_all(&las)));
    // The input's point format and version.
    let fmt = |p: &Path| {
        myriad_io::open(p, &OpenOptions::default())
            .unwrap()
            .info()
            .version
            .clone()
    };
    assert_eq!(fmt(&back), fmt(&las));

    // An existing output is not replaced without force.
    let before = std::fs::read(&out).unwrap();
    let err = convert(std::slice::from_ref(&las), &o, &Silent).unwrap_err();
    assert!(err.to_string().contains("--force"), "{err}");
    assert_eq!(std::fs::read(&out).unwrap(), before);
}

/// `mwkd` with the fan-out and clustering grid asked for (`convert --fanout N --grid K`,
/// Goswami et al. 2010, tables II and IV): no node has more than N children and some have N, a
/// smaller N makes a deeper tree, the dataset records both, and nothing is lost.
#[test]
fn mwkd_takes_the_fanout_and_grid_asked_for() {
    let d = tempdir("convert-fanout");
    let las = synth(&d, 200_000, 9);
    let input = records(&read_all(&las));
    let mut depths = Vec::new();
    for fanout in [2usize, 3, 7] {
        let out = d.join(format!("n{fanout}.myr"));
        let mut o = options(&out);
        o.structure = Structure::Mwkd;
        o.memory = myriad_build::convert::MIN_MEMORY;
        o.chunk_points = Some(30_000);
        o.params.capacity = 4096;
        o.threads = 2;
        o.fanout = Some(fanout);
        o.grid = Some(35);
        convert(std::slice::from_ref(&las), &o, &Silent).unwrap();
        let ds = Dataset::open(&out).unwrap();
        assert_eq!(
            ds.meta.parameters["fanout"], fanout,
            "{}",
            ds.meta.parameters
        );
        assert_eq!(ds.meta.parameters["grid"], 35, "{}", ds.meta.parameters);
        let (nodes, damage) = ds.nodes();
        assert!(damage.is_empty());
        let mut children = std::collections::HashMap::new();
        for n in nodes.iter().filter(|n| n.key.level > 0) {
            *children.entry(n.key.parent()).or_insert(0usize) += 1;
        }
        let most = children.values().copied().max().unwrap_or(0);
        assert_eq!(most, fanout, "N = {fanout}: {children:?}");
        assert!(nodes.iter().all(|n| n.points as usize <= 4096));
        let back = d.join(format!("n{fanout}.las"));
        extract(&ds, &back, &ExtractOptions::default()).unwrap();
        assert!(
            records(&read_all(&back)) == input,
            "N = {fanout}: points differ"
        );
        depths.push(ds.meta.depth);
    }
    assert!(
        depths[0] > depths[1] && depths[1] > depths[2],
        "depths {depths:?}"
    );
}

/// Every structure over many chunks (so kd groups them and every structure builds levels above
/// them): nothing lost, invariants hold, the stored shapes are those of the structure.
#[test]
fn every_structure_many_chunks() {
    let d = tempdir("convert-structures");
    let las = synth(&d, 200_000, 5);
    let input = records(&read_all(&las));
    for structure in Structure::ALL {
        let out = d.join(format!("{}.myr", structure.name()));
        let mut o = options(&out);
        o.structure = structure;
        o.memory = myriad_build::convert::MIN_MEMORY;
        o.chunk_points = Some(30_000);
        o.params.capacity = 4096;
        o.threads = 2;
        let s = convert(std::slice::from_ref(&las), &o, &Silent).unwrap();
        assert!(s.chunks >= 4 && s.depth >= 3, "{structure:?}: {s:?}");
        let ds = Dataset::open(&out).unwrap();
        let r = verify(&ds, |_| {});
        assert!(r.damage.is_empty(), "{structure:?}: {:?}", r.damage);
        let back = d.join(format!("{}.las", structure.name()));
        extract(&ds, &back, &ExtractOptions::default()).unwrap();
        assert!(
            records(&read_all(&back)) == input,
            "{structure:?}: points differ"
        );
        let (nodes, _) = ds.nodes();
        let kd = structure == Structure::Kd;
        let mwkd = structure == Structure::Mwkd;
        let layered = structure == Structure::Layered;
        assert!(
            nodes.iter().all(|n| n.bounds.is_some() == (kd || mwkd)),
            "{structure:?}"
        );
        assert!(
            nodes.iter().all(|n| n.contour.is_some() == layered),
            "{structure:?}"
        );
        assert!(
            nodes.iter().all(|n| n.splats.is_some() == mwkd),
            "{structure:?}"
        );
        if mwkd {
            // Inner nodes are aggregates, leaves the original points; every splat page reads.
            let inner = nodes.iter().filter(|n| n.aggregate()).count();
            assert!(inner > 0 && inner < nodes.len());
            for n in &nodes {
                let s = ds.read_splats(n).unwrap().unwrap();
                assert_eq!(s.radii.len(), n.points as usize);
                assert!(s.radii.iter().all(|&r| r > 0.0));
            }
        }
        if kd {
            // Binary: only the first two octants of a key are used.
            assert!(
                nodes
                    .iter()
                    .all(|n| n.key.cell[1] == 0 && n.key.cell[2] == 0)
            );
        }
        if layered {
            // Roof tops and streets of the synthetic city are flat: some contours are tilted or
            // thin boxes, not all axis-aligned.
            let oriented = nodes
                .iter()
                .filter(|n| n.contour.unwrap().axes[0] != [1.0, 0.0, 0.0])
                .count();
            assert!(oriented > 0, "no flat node among {}", nodes.len());
            // Every node that passes points down has the contour of its own points (verify
            // checked that they lie in it).
            let keys: std::collections::HashSet<_> = nodes.iter().map(|n| n.key).collect();
            let parents: std::collections::HashSet<_> = nodes
                .iter()
                .filter(|n| n.key.level > 0 && keys.contains(&n.key.parent()))
                .map(|n| n.key.parent())
                .collect();
            assert!(parents.len() > 1);
            for n in nodes.iter().filter(|n| parents.contains(&n.key)) {
                assert!(n.detail.is_some(), "{:?} has no own contour", n.key);
            }
        }
        assert_eq!(
            ds.meta.structure,
            if structure == Structure::Octree {
                "nested-octree"
            } else {
                structure.name()
            }
        );
    }
}

/// Every file of ../shared/data, in every format, with the layered, kd and mwkd structures: the
/// points read back from the nodes (mwkd: its leaves; its inner nodes hold aggregates) are the
/// input's, every field (positions on the dataset's quantization grid), and the dataset
/// verifies. (The octree's test goes through extraction:
/// `nothing_lost_for_every_las_file_in_shared_data`.)
#[test]
fn nothing_lost_for_every_file_and_structure() {
    let Some(dir) = data_dir() else { return };
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| myriad_io::detect(p).is_ok())
        .collect();
    files.sort();
    assert!(files.len() >= 30, "{} point cloud files", files.len());
    let d = tempdir("convert-every");
    for f in &files {
        let mut input = read_all(f);
        for structure in [Structure::Layered, Structure::Kd, Structure::Mwkd] {
            let out = d.join("a.myr");
            let mut o = options(&out);
            o.structure = structure;
            o.force = true;
            o.params.capacity = 16_384;
            let s = convert(std::slice::from_ref(f), &o, &Silent)
                .unwrap_or_else(|e| panic!("{} {structure:?}: {e}", f.display()));
            let ds = Dataset::open(&out).unwrap();
            let r = verify(&ds, |_| {});
            assert!(
                r.damage.is_empty(),
                "{} {structure:?}: {:?}",
                f.display(),
                r.damage
            );
            assert_eq!(s.points as usize, input.len(), "{}", f.display());
            let q = ds.meta.quantization;
            for p in &mut input.positions {
                *p = q.to_world(q.to_int(*p));
            }
            let mut stored = PointBatch::with_schema(&ds.meta.schema, 0);
            for n in ds.nodes().0.iter().filter(|n| !n.aggregate()) {
                stored.append(&ds.read_node(n).unwrap());
            }
            assert!(
                records(&stored) == records(&input),
                "{} {structure:?}: the stored points differ from the input's",
                f.display()
            );
        }
    }
}

#[test]
fn box_and_spacing_queries() {
    let d = tempdir("convert-query");
    let las = synth(&d, 200_000, 5);
    let out = d.join("q.myr");
    let mut o = options(&out);
    o.params.capacity = 4096;
    convert(std::slice::from_ref(&las), &o, &Silent).unwrap();
    let ds = Dataset::open(&out).unwrap();
    let all = read_all(&las);
    let b = ds.meta.bounds;
    let c = b.center();
    let bx = Aabb::new([b.min[0], b.min[1], b.min[2]], [c[0], c[1], b.max[2]]);
    let part = d.join("part.laz");
    let e = extract(
        &ds,
        &part,
        &ExtractOptions {
            bbox: Some(bx),
            ..Default::default()
        },
    )
    .unwrap();
    let mut inside = all.clone();
    let keep: Vec<bool> = all.positions.iter().map(|&p| bx.contains(p)).collect();
    inside.retain_mask(&keep);
    assert!(inside.len() > 10_000 && inside.len() < all.len());
    assert_eq!(e.points as usize, inside.len());
    assert_eq!(records(&read_all(&part)), records(&inside));

    // Coarser spacing, fewer points.
    let mut last = all.len() as u64 + 1;
    let originals = records(&all);
    for spacing in [0.5, 2.0, 8.0, 1e6] {
        let p = d.join(format!("lod{spacing}.ply"));
        let e = extract(
            &ds,
            &p,
            &ExtractOptions {
                spacing: Some(spacing),
                ..Default::default()
            },
        )
        .unwrap();
        if spacing == 1e6 {
            assert_eq!(e.points, 0, "nothing is as coarse as a megametre");
        } else {
            assert!(
                e.points < last && e.points >= 1,
                "spacing {spacing}: {}",
                e.points
            );
        }
        last = e.points;
    }
    // At 2 m, the points are originals and about one per 2 m cell of the surface.
    let p = d.join("lod.las");
    extract(
        &ds,
        &p,
        &ExtractOptions {
            spacing: Some(2.0),
            ..Default::default()
        },
    )
    .unwrap();
    let lod = records(&read_all(&p));
    assert!(lod.iter().all(|r| originals.binary_search(r).is_ok()));
    let area = (b.max[0] - b.min[0]) * (b.max[1] - b.min[1]);
    let n = lod.len() as f64;
    assert!(
        n > area / 64.0 && n < area,
        "{n} points at 2 m over {area} m²"
    );
}

#[test]
fn damaged_pages_are_named_and_skipped() {
    let d = tempdir("convert-damage");
    let las = synth(&d, 100_000, 5);
    let out = d.join("d.myr");
    let mut o = options(&out);
    o.params.capacity = 4096;
    convert(std::slice::from_ref(&las), &o, &Silent).unwrap();
    let good = std::fs::read(&out).unwrap();
    let ds = Dataset::open(&out).unwrap();
    let (nodes, damage) = ds.nodes();
    assert!(damage.is_empty());
    let victim = nodes
        .iter()
        .filter(|n| n.points > 100)
        .nth(3)
        .unwrap()
        .clone();
    drop(ds);

    // A flipped byte in each part of one node page (head, directory, column data).
    for at in [
        10,
        40,
        victim.page.length as u64 / 2,
        victim.page.length as u64 - 1,
    ] {
        let mut bytes = good.clone();
        bytes[(victim.page.offset + at) as usize] ^= 0x10;
        std::fs::write(&out, &bytes).unwrap();
        let ds = Dataset::open(&out).unwrap();
        let r = verify(&ds, |_| {});
        assert_eq!(r.damage.len(), 1, "flip at {at}: {:?}", r.damage);
        assert_eq!(r.damage[0].key, victim.key);
        let msg = ds.damage_error(&r.damage[0]).to_string();
        assert!(msg.contains(&victim.key.to_string()), "{msg}");
        assert!(ds.read_node(&victim).is_err());
        // A reader goes on without the node.
        let e = extract(
            &ds,
            &d.join("rest.las"),
            &ExtractOptions {
                force: true,
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(e.damage.len(), 1);
        assert_eq!(e.points, 100_000 - victim.points as u64);
    }

    // A flipped byte in the root hierarchy page: the subtree is reported, nothing panics.
    let ds = Dataset::open(&out).unwrap();
    let root = ds.root_page().page;
    drop(ds);
    let mut bytes = good.clone();
    bytes[(root.offset + 20) as usize] ^= 1;
    std::fs::write(&out, &bytes).unwrap();
    let ds = Dataset::open(&out).unwrap();
    let r = verify(&ds, |_| {});
    assert!(r.damage.iter().any(|d| d.subtree), "{:?}", r.damage);

    // Header, metadata, truncation: the dataset does not open, and says where.
    for at in [0usize, 20, good.len() - 10] {
        let mut bytes = good.clone();
        bytes[at] ^= 1;
        std::fs::write(&out, &bytes).unwrap();
        let err = Dataset::open(&out).err().expect("damaged header opened");
        assert!(err.to_string().contains("byte"), "{err}");
    }
    std::fs::write(&out, &good[..good.len() - 1]).unwrap();
    assert!(Dataset::open(&out).is_err());
}

#[test]
fn inputs_of_several_formats_merge() {
    let d = tempdir("convert-merge");
    let las = synth(&d, 50_000, 5);
    let all = read_all(&las);
    // The same area as PLY (float coordinates, colour only) from the first points.
    let ply = d.join("part.ply");
    let mut sink = myriad_io::ply::PlySink::create(
        &ply,
        &myriad_core::Schema::new(vec![myriad_core::Attribute::Rgb]),
        false,
    )
    .unwrap();
    let mut some = all.slice(0..1000);
    some.positions.iter_mut().for_each(|p| p[2] += 0.12345);
    let mut rgb_only = PointBatch::with_schema(
        &myriad_core::Schema::new(vec![myriad_core::Attribute::Rgb]),
        0,
    );
    rgb_only.positions = some.positions.clone();
    rgb_only.rgb = some.rgb.clone();
    sink.write(&rgb_only).unwrap();
    sink.finish().unwrap();
    let out = d.join("m.myr");
    let mut o = options(&out);
    o.precision = 0.0001;
    let s = convert(&[las.clone(), ply.clone()], &o, &Silent).unwrap();
    assert_eq!(s.points, 51_000);
    let ds = Dataset::open(&out).unwrap();
    assert_eq!(ds.meta.sources.len(), 2);
    // The finer of the two grids (LAS 1 mm, PLY 0.1 mm).
    assert_eq!(ds.meta.quantization.scale, [0.0001; 3]);
    let back = d.join("m.las");
    extract(&ds, &back, &ExtractOptions::default()).unwrap();
    let b = read_all(&back);
    assert_eq!(b.len(), 51_000);
    // The PLY points are there, on their 0.1 mm grid.
    let z: Vec<f64> = rgb_only.positions.iter().map(|p| p[2]).collect();
    for want in z.iter().take(50) {
        assert!(b.positions.iter().any(|p| (p[2] - want).abs() < 0.00006));
    }
}

#[test]
fn nothing_lost_for_every_las_file_in_shared_data() {
    let Some(dir) = data_dir() else { return };
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            p.extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| e.eq_ignore_ascii_case("las") || e.eq_ignore_ascii_case("laz"))
        })
        .collect();
    files.sort();
    assert!(files.len() >= 20, "{} LAS/LAZ files", files.len());
    let d = tempdir("convert-real");
    for f in &files {
        let name = f.file_stem().unwrap().to_str().unwrap();
        let out = d.join(format!("{name}.myr"));
        let mut o = options(&out);
        o.params.capacity = 16_384;
        let s = convert(std::slice::from_ref(f), &o, &Silent)
            .unwrap_or_else(|e| panic!("{}: {e}", f.display()));
        let ds = Dataset::open(&out).unwrap();
        let r = verify(&ds, |_| {});
        assert!(r.damage.is_empty(), "{}: {:?}", f.display(), r.damage);
        let back = d.join(format!("{name}.las"));
        extract(&ds, &back, &ExtractOptions::default()).unwrap();
        let input = read_all(f);
        let output = read_all(&back);
        assert_eq!(s.points as usize, input.len(), "{}", f.display());
        assert_eq!(output.schema(), input.schema(), "{}", f.display());
        assert!(
            records(&output) == records(&input),
            "{}: the extracted points differ from the input's",
            f.display()
        );
        let info = |p: &Path| {
            let s = myriad_io::open(p, &OpenOptions::default()).unwrap();
            let i = s.info();
            (
                i.version.replace("COPC 1.0, ", ""),
                i.scale,
                i.offset,
                i.crs.clone(),
            )
        };
        let (vi, si, oi, ci) = info(f);
        let (vo, so, oo, co) = info(&back);
        assert_eq!((so, oo), (si, oi), "{}", f.display());
        assert_eq!(ci, co, "{}: CRS", f.display());
        assert!(
            vi.contains(&vo) || vo.contains(&vi),
            "{}: {vi} / {vo}",
            f.display()
        );
        // The same records through COPC (LAS 1.4 format 6-8): every field but what the summary
        // says COPC cannot hold (wave packets; legacy scan angle ranks within 0.003 degrees), and
        // without the fields formats 6-8 add (GPS time, scanner channel) where the input had none.
        let copc = d.join(format!("{name}.copc.laz"));
        let mut eo = ExportOptions::new(Target::Copc);
        eo.force = true;
        let es =
            export(&ds, &copc, &eo, &Silent).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
        assert!(
            es.damage.is_empty() && es.points == s.points,
            "{}",
            f.display()
        );
        let mut from_copc = read_all(&copc);
        let mut from_las = output;
        let legacy = !input.schema().has(&myriad_core::Attribute::ScannerChannel);
        if legacy {
            from_copc.scanner_channel = None;
            for b in [&mut from_copc, &mut from_las] {
                b.scan_angle
                    .iter_mut()
                    .flatten()
                    .for_each(|a| *a = a.round());
            }
        }
        if input.gps_time.is_none() {
            from_copc.gps_time = None;
        }
        if input.wave_packet.is_some() {
            assert!(
                es.not_kept.iter().any(|l| l.contains("wave")),
                "{}",
                f.display()
            );
            from_las.wave_packet = None;
        }
        assert!(
            records(&from_copc) == records(&from_las),
            "{}: the COPC export's points differ from the dataset's",
            f.display()
        );
        let (_, _, _, cc) = info(&copc);
        if co.as_deref().is_some_and(|c| !c.starts_with("EPSG:")) {
            assert_eq!(cc, co, "{}: CRS in the COPC export", f.display());
        }
        std::fs::remove_file(&out).unwrap();
        std::fs::remove_file(&back).unwrap();
        std::fs::remove_file(&copc).unwrap();
    }
}

#[test]
fn one_dataset_read_from_many_threads() {
    fn shareable<T: Send + Sync>(_: &T) {}
    let d = tempdir("convert-threads");
    let las = synth(&d, 60_000, 5);
    let out = d.join("t.myr");
    let mut o = options(&out);
    o.params.capacity = 2048;
    convert(std::slice::from_ref(&las), &o, &Silent).unwrap();
    let ds = Dataset::open(&out).unwrap();
    shareable(&ds);
    let (nodes, _) = ds.nodes();
    assert!(nodes.len() > 8);
    let totals: Vec<u64> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..4)
            .map(|t| {
                let (ds, nodes) = (&ds, &nodes);
                s.spawn(move || {
                    // Each thread reads every node, starting at a different one.
                    (0..nodes.len())
                        .map(|k| {
                            let n = &nodes[(k + t * 7) % nodes.len()];
                            ds.read_node(n).unwrap().len() as u64
                        })
                        .sum()
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    assert_eq!(totals, vec![60_000; 4]);
}

#[test]
fn a_header_that_understates_its_bounds() {
    let d = tempdir("convert-bounds");
    let las = synth(&d, 100_000, 5);
    // LAS 1.4 header: max x at byte 179, min x at 187 (f64). Claim half the x extent.
    let mut bytes = std::fs::read(&las).unwrap();
    let f = |b: &[u8], at: usize| f64::from_le_bytes(b[at..at + 8].try_into().unwrap());
    let (max_x, min_x) = (f(&bytes, 179), f(&bytes, 187));
    let half = min_x + (max_x - min_x) / 2.0;
    bytes[179..187].copy_from_slice(&half.to_le_bytes());
    let lying = d.join("lying.las");
    std::fs::write(&lying, &bytes).unwrap();
    let out = d.join("b.myr");
    let mut o = options(&out);
    o.params.capacity = 4096;
    o.chunk_points = Some(20_000);
    convert(std::slice::from_ref(&lying), &o, &Silent).unwrap();
    let ds = Dataset::open(&out).unwrap();
    assert!(ds.meta.root.max[0] >= max_x, "root cube {:?}", ds.meta.root);
    // Every point inside its node's cube; nothing lost.
    let r = verify(&ds, |_| {});
    assert!(r.damage.is_empty(), "{:?}", r.damage);
    let back = d.join("back.las");
    extract(&ds, &back, &ExtractOptions::default()).unwrap();
    assert_eq!(records(&read_all(&back)), records(&read_all(&lying)));
}
