// What the fuzz targets of the parsers a user, a file or a client reaches do with their input
// (`--where` and `--classes`, polygons and lines, GeoJSON and DXF imports, the server's ranges,
// query strings and credentials, the cloud formats COPC, EPT and Potree 2.0), shared by the
// targets (`fuzz_targets/`) and `crates/myriad/tests/fuzz_replay.rs`, which replays the
// committed corpora. Included with `include!`; needs the `myriad_core`, `myriad_io`,
// `myriad_format`, `myriad_measure` and `myriad_serve` crates. Every function must return, or
// panic only where an invariant a user relies on fails (the asserts).

/// A folder in RAM for this process and thread (replay runs in test threads).
fn scratch_dir(what: &str) -> std::path::PathBuf {
    let base = if std::path::Path::new("/dev/shm").is_dir() { "/dev/shm" } else { "/tmp" };
    let thread =
        format!("{:?}", std::thread::current().id()).replace(|c: char| !c.is_ascii_digit(), "");
    let d = std::path::PathBuf::from(format!(
        "{base}/myriad-fuzz-{what}-{}-{thread}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// `--classes` (the first line) and `--where` (each further line): parsed, bound to a schema
/// with the LAS attributes and an extra-bytes dimension, and run over a few points; a filter
/// that parses and binds keeps a subset, the same twice.
pub fn filter(data: &[u8]) {
    use myriad_core::{Attribute, ExtraDim, ExtraType, PointBatch, Schema};
    let text = String::from_utf8_lossy(data);
    let mut lines = text.lines();
    let classes = lines.next().filter(|l| !l.is_empty());
    let wheres: Vec<String> = lines.take(16).map(str::to_string).collect();
    let Ok(f) = myriad_measure::Filter::parse(classes, &wheres) else { return };
    let extra = ExtraDim {
        name: "Amplitude".into(),
        data_type: ExtraType::I16,
        offset: 0,
        description: String::new(),
        scale: Some(0.01),
        add_offset: Some(-3.0),
    };
    let schema = Schema {
        attributes: vec![
            Attribute::Intensity,
            Attribute::Classification,
            Attribute::ReturnNumber,
            Attribute::NumberOfReturns,
            Attribute::GpsTime,
            Attribute::PointSourceId,
            Attribute::Extra(extra),
        ],
        extra_bytes: 2,
    };
    let Ok(bound) = f.bind(&schema) else { return };
    let n = 64;
    let mut b = PointBatch::with_schema(&schema, n);
    for i in 0..n {
        b.positions.push([i as f64, -(i as f64), i as f64 * 1e9]);
        b.intensity.as_mut().unwrap().push((i * 1021) as u16);
        b.classification.as_mut().unwrap().push((i * 7 % 256) as u8);
        b.return_number.as_mut().unwrap().push((i % 8) as u8);
        b.number_of_returns.as_mut().unwrap().push((i % 5) as u8);
        b.gps_time.as_mut().unwrap().push(i as f64 * 1e5 - 3e6);
        b.point_source_id.as_mut().unwrap().push((i * 977) as u16);
    }
    b.extra_bytes = Some((0..n * 2).map(|k| (k * 37) as u8).collect());
    b.extra_stride = 2;
    let mask = bound.mask(&b);
    assert_eq!(mask.len(), n);
    assert_eq!(mask, bound.mask(&b), "a filter keeps the same points twice");
}

/// Polygons and lines: the three file forms, the inline list, then the polygon's and the
/// corridor's checks and tests on a few points (inside-or-out and stations, against a scan of
/// every edge).
pub fn shape(data: &[u8]) {
    use myriad_measure::Region;
    use myriad_measure::shape::{Want, parse};
    let Some((&first, rest)) = data.split_first() else { return };
    let text = String::from_utf8_lossy(rest);
    let name = ["a.geojson", "a.wkt", "a.csv", "a"][(first % 4) as usize];
    let want = if first & 4 == 0 { Want::Polygon } else { Want::Line };
    let pts = match parse(&text, name, want) {
        Ok(s) => s.points,
        Err(e) => {
            assert!(!e.contains('\n') || e.len() < 10_000, "errors are one line");
            match myriad_measure::corridor::parse_xy_list(&text, "--polygon", 2) {
                Ok(p) => p,
                Err(_) => return,
            }
        }
    };
    let pts: Vec<[f64; 2]> = pts.into_iter().take(4096).collect();
    let probe = |i: usize| {
        let p = pts[i % pts.len()];
        let q = pts[(i * 7 + 3) % pts.len()];
        [(p[0] + q[0]) / 2.0, (p[1] + q[1]) / 2.0 + i as f64 * 1e-3]
    };
    if let Ok(poly) = myriad_measure::Polygon::new(&pts) {
        assert!(poly.area() > 0.0);
        let v = poly.vertices();
        for i in 0..32 {
            let [x, y] = probe(i);
            let mut scan = false;
            for k in 0..v.len() {
                let (a, b) = (v[k], v[(k + 1) % v.len()]);
                if (a[1] > y) != (b[1] > y)
                    && x < a[0] + (y - a[1]) / (b[1] - a[1]) * (b[0] - a[0])
                {
                    scan = !scan;
                }
            }
            assert_eq!(poly.contains_xy(x, y), scan, "{x},{y}: the index and a scan agree");
            let m = poly.with_margin(1.0);
            let _ = m.near_edge(x, y);
            let _ = m.meets(&myriad_core::Aabb::new([x, y, 0.0], [x + 1.0, y + 1.0, 1.0]));
        }
    }
    if let Ok(c) = myriad_measure::Corridor::new(&pts, 2.0) {
        for i in 0..32 {
            let [x, y] = probe(i);
            if let Some((along, across)) = c.station(x, y) {
                assert!(along >= 0.0 && along <= c.length() + 1e-6 * c.length().max(1.0));
                assert!(across.abs() <= 1.0 + 1e-9 * across.abs().max(1.0), "{across}");
            }
        }
    }
}

/// Saved work from GeoJSON, a work sidecar or DXF (the first byte picks): imported, merged into
/// empty work, written back as GeoJSON and read again.
pub fn import(data: &[u8]) {
    let Some((&first, rest)) = data.split_first() else { return };
    let ext = ["geojson", "json", "dxf"][(first % 3) as usize];
    let d = scratch_dir("import");
    let path = d.join(format!("work.{ext}"));
    std::fs::write(&path, rest).unwrap();
    if let Ok(w) = myriad_measure::files::import_work(&path) {
        let mut all = myriad_measure::work::Work::new(None);
        if all.merge(w).is_ok() {
            let back = myriad_measure::work::Work::from_geojson(&all.to_geojson());
            assert!(back.is_ok(), "work written as GeoJSON reads back: {back:?}");
        }
    }
    let _ = std::fs::remove_dir_all(&d);
}

/// The server's parsers of what a client sends, by line: a `Range` header, a download's query
/// string, and a request's path?query with its `Authorization` and `Cookie` headers (checked
/// against a token file none of whose tokens the input can know but by `Bearer`).
pub fn query(data: &[u8]) {
    use myriad_serve::access::{Access, Verdict};
    let text = String::from_utf8_lossy(data);
    let mut l = text.split('\n');
    let (range, q, path, auth, cookie) = (
        l.next().unwrap_or(""),
        l.next().unwrap_or(""),
        l.next().unwrap_or(""),
        l.next(),
        l.next(),
    );
    for len in [0u64, 1, 1000, u64::MAX] {
        if let myriad_serve::range::Ranges::Some(r) = myriad_serve::range::parse(range, len) {
            assert!(r.len() <= myriad_serve::range::MAX_RANGES);
            assert!(r.iter().all(|&(a, b)| a <= b && b < len), "{range}: {r:?} of {len}");
        }
    }
    if let Ok(q) = myriad_serve::download::parse_query(q) {
        if let Some(b) = q.bbox {
            assert!((0..3).all(|a| b.min[a] <= b.max[a]));
        }
        assert!(q.spacing.is_none_or(|s| s.is_finite() && s > 0.0));
    }
    let _ = myriad_serve::access::parse_duration(q);
    let access = Access::from_tokens("fuzzing-token-0123456789\n").unwrap();
    let (p, qs) = match path.split_once('?') {
        Some((p, q)) => (p, Some(q)),
        None => (path, None),
    };
    let v = access.check(p, qs, auth, cookie, 1_800_000_000);
    if matches!(v, Verdict::Allowed | Verdict::AllowedSetting(..)) {
        let bearer = auth.and_then(|a| a.strip_prefix("Bearer ")).map(str::trim);
        assert_eq!(bearer, Some("fuzzing-token-0123456789"), "allowed without the token: {path}");
    }
}

/// The part separator of the `cloud` target's input.
pub const PART: &[u8] = b"\n@@@@\n";

/// The cloud formats read in place: the first byte picks COPC (the rest one file), EPT (parts
/// separated by [`PART`]: ept.json, the root hierarchy page, then the data of the nodes
/// 0-0-0-0, 1-1-1-1, 2-2-2-3, 3-4-4-7 and 1-0-0-0, each written as .laz, .bin and .zst) or
/// Potree 2.0 (metadata.json, hierarchy.bin, octree.bin); the dataset opened and its nodes read
/// (capped), each node's points the count its hierarchy says.
pub fn cloud(data: &[u8]) {
    let Some((&first, rest)) = data.split_first() else { return };
    let d = scratch_dir("cloud");
    let mut parts = Vec::new();
    let mut s = rest;
    while let Some(i) = s.windows(PART.len()).position(|w| w == PART) {
        parts.push(&s[..i]);
        s = &s[i + PART.len()..];
    }
    parts.push(s);
    let open = match first % 3 {
        0 => {
            let p = d.join("x.copc.laz");
            std::fs::write(&p, rest).unwrap();
            p
        }
        1 => {
            std::fs::create_dir_all(d.join("ept-hierarchy")).unwrap();
            std::fs::create_dir_all(d.join("ept-data")).unwrap();
            std::fs::write(d.join("ept.json"), parts[0]).unwrap();
            if let Some(h) = parts.get(1) {
                std::fs::write(d.join("ept-hierarchy/0-0-0-0.json"), h).unwrap();
            }
            let keys = ["0-0-0-0", "1-1-1-1", "2-2-2-3", "3-4-4-7", "1-0-0-0"];
            for (k, p) in keys.iter().zip(parts.iter().skip(2)) {
                for ext in ["laz", "bin", "zst"] {
                    std::fs::write(d.join(format!("ept-data/{k}.{ext}")), p).unwrap();
                }
            }
            d.join("ept.json")
        }
        _ => {
            let names = ["metadata.json", "hierarchy.bin", "octree.bin"];
            for (n, p) in names.iter().zip(&parts) {
                std::fs::write(d.join(n), p).unwrap();
            }
            d.clone()
        }
    };
    if let Ok(ds) = myriad_format::Dataset::open(&open) {
        let (nodes, _damage) = ds.nodes();
        let mut points = 0usize;
        for n in nodes.iter().take(64) {
            if let Ok(b) = ds.read_node(n) {
                assert!(b.is_consistent());
                assert_eq!(b.len(), n.points as usize, "a node holds what its hierarchy says");
                points += b.len();
            }
            if points > 2_000_000 {
                break;
            }
        }
    }
    let _ = std::fs::remove_dir_all(&d);
}

/// An edits file (`NAME.edits.json`, first byte even; also read as a viewer's change) or a ground
/// surface (odd; its isolated cubes looked up too): parsed, bound to
/// a schema with classes and intensity and applied to a few points (an edits file), or opened
/// and read at points across its grid (a surface); an edits file that parses writes back to
/// the same layer.
pub fn edits(data: &[u8]) {
    use myriad_core::{Aabb, Attribute, PointBatch, Schema};
    use myriad_format::edits::Edits;
    let Some((&mode, rest)) = data.split_first() else { return };
    if mode % 2 == 1 {
        let d = scratch_dir("surface");
        let path = d.join("s.surface");
        std::fs::write(&path, rest).unwrap();
        if let Ok(s) = myriad_measure::ground::surface::Surface::open(&path) {
            let p = s.placement;
            for i in 0..16u32 {
                let (x, y) = (
                    p.x0 + (i as f64 / 15.0) * p.nx as f64 * p.cell,
                    p.y0 + ((15 - i) as f64 / 15.0) * p.ny as f64 * p.cell,
                );
                if let Some(t) = s.tile_of(x, y)
                    && let Ok(Some(cells)) = s.tile(t)
                    && let Some(h) = s.height(t, &cells, x, y)
                {
                    assert!(!h.z.is_nan() && h.slope >= 0.0);
                }
                // Isolated cubes: a lookup anywhere, inside the grid or not.
                let _ = s.is_isolated(x, y, p.cell * i as f64);
            }
        }
        let _ = std::fs::remove_dir_all(&d);
        return;
    }
    let Ok(text) = std::str::from_utf8(rest) else { return };
    // A viewer's change (`serve --edit`'s POST body): one line of error or a change.
    let _ = myriad_measure::edits::Change::parse(text);
    let Ok(layer) = myriad_measure::edits::Layer::parse(text) else { return };
    assert_eq!(
        myriad_measure::edits::Layer::parse(&layer.to_json()).as_ref(),
        Ok(&layer),
        "an edits file writes back to itself"
    );
    let schema = Schema::new(vec![Attribute::Classification, Attribute::Intensity]);
    // Ground edits name surfaces that are not there: an error, as when a dataset opens.
    let Ok(c) = layer.compile(&schema, std::path::Path::new("/nonexistent")) else { return };
    let n = 64;
    let mut b = PointBatch::with_schema(&schema, n);
    for i in 0..n {
        b.positions.push([i as f64 * 3.0 - 50.0, i as f64 * -7.0 + 100.0, (i % 9) as f64]);
        b.classification.as_mut().unwrap().push((i * 5 % 256) as u8);
        b.intensity.as_mut().unwrap().push((i * 1009) as u16);
    }
    let cube = Aabb::new([-1e3; 3], [1e3; 3]);
    if let Ok(Some(keep)) = c.apply(&cube, &mut b) {
        assert_eq!(keep.iter().filter(|k| **k).count(), b.len());
    }
}
