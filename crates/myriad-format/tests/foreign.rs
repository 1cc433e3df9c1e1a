//! The field's cloud formats read in place (issue 66): COPC files from two writers, the five EPT
//! datasets Entwine wrote (laszip, zstandard, binary, colour, one damaged node) and Potree 2.0
//! from PotreeConverter (DEFAULT and BROTLI) open as datasets holding every point of their
//! source once; damaged parts are named and the rest reads; over HTTP the first image of a COPC
//! costs three requests, and a server that ignores ranges is refused before a whole file comes.

use myriad_core::{NodeKey, PointBatch};
use myriad_format::Dataset;
use myriad_format::hierarchy::{PAGE_LEVELS, page_root};
use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};

fn shared(rel: &str) -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared")
        .join(rel);
    if p.exists() {
        Some(p)
    } else {
        eprintln!("SKIPPED: {} not found", p.display());
        None
    }
}

fn tempdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("myriad-foreign-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Count and per-axis sums of positions (order-free).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Sums {
    n: u64,
    sum: [f64; 3],
}

impl Sums {
    fn add(&mut self, b: &PointBatch) {
        self.n += b.len() as u64;
        for p in &b.positions {
            for a in 0..3 {
                self.sum[a] += p[a];
            }
        }
    }
    fn close_to(&self, o: &Sums, tol: f64) -> bool {
        self.n == o.n && (0..3).all(|a| (self.sum[a] - o.sum[a]).abs() <= tol * self.n as f64)
    }
}

fn zero() -> Sums {
    Sums {
        n: 0,
        sum: [0.0; 3],
    }
}

/// Every point of a LAS/LAZ file, read as a scan.
fn scan_sums(path: &Path) -> Sums {
    let mut src = myriad_io::open(path, &myriad_io::OpenOptions::default()).unwrap();
    let mut s = zero();
    while let Some(b) = src.read_batch(1 << 16).unwrap() {
        s.add(&b);
    }
    s
}

/// Every node of a dataset read: the sums, and the nodes' keys that did not read.
fn dataset_sums(ds: &Dataset) -> (Sums, Vec<(NodeKey, String)>) {
    let (nodes, damage) = ds.nodes();
    assert!(damage.is_empty(), "{damage:?}");
    let mut s = zero();
    let mut bad = Vec::new();
    for e in &nodes {
        // Each entry lies on the page its key's level puts it on (what the selection expects).
        assert_eq!(page_root(e.key).level % PAGE_LEVELS, 0);
        match ds.read_node(e) {
            Ok(b) => {
                assert_eq!(b.len(), e.points as usize, "node {}", e.key);
                // Within a grid step of the node's cube (writers round onto their grid).
                let cube = e.key.bounds(&ds.meta.root);
                let step = ds.meta.quantization.scale.map(|s| s * 1.01);
                for p in &b.positions {
                    assert!(
                        (0..3).all(|a| p[a] >= cube.min[a] - step[a] && p[a] <= cube.max[a] + step[a]),
                        "node {}: {p:?} outside {cube:?}",
                        e.key
                    );
                }
                s.add(&b);
            }
            Err(d) => bad.push((e.key, d.message)),
        }
    }
    (s, bad)
}

#[test]
fn copc_files_of_two_writers_hold_every_point_once() {
    for name in [
        "PDAL__copc_lone-star.copc.laz",
        "potree__lion_takanawa.copc.laz",
    ] {
        let Some(path) = shared(&format!("data/{name}")) else {
            return;
        };
        let ds = Dataset::open(&path).unwrap();
        assert_eq!(ds.foreign_format(), Some("COPC 1.0"));
        let (sums, bad) = dataset_sums(&ds);
        assert!(bad.is_empty(), "{bad:?}");
        let want = scan_sums(&path);
        assert_eq!(ds.meta.points, want.n);
        assert!(sums.close_to(&want, 1e-6), "{name}: {sums:?} vs {want:?}");
        // The schema is the file's: the root node has the columns a LAS 1.4 reader gives.
        let root = ds.overview().unwrap();
        assert!(root.gps_time.is_some() && root.classification.is_some());
        assert_eq!(ds.fetched(), None);
    }
}

#[test]
fn ept_datasets_as_entwine_wrote_them() {
    let Some(ept) = shared("ept") else {
        return;
    };
    // The lone-star scan as EPT (laszip) holds the points of the COPC file of the same scan.
    let ds = Dataset::open(&ept.join("lone-star-laszip")).unwrap();
    assert_eq!(ds.foreign_format(), Some("EPT"));
    assert_eq!(ds.meta.points, 518_862);
    let (sums, bad) = dataset_sums(&ds);
    assert!(bad.is_empty(), "{bad:?}");
    if let Some(copc) = shared("data/PDAL__copc_lone-star.copc.laz") {
        assert!(sums.close_to(&scan_sums(&copc), 1e-3), "{sums:?}");
    }
    assert!(
        ds.meta
            .crs
            .as_deref()
            .is_some_and(|c| c.contains("UTM zone 12N"))
    );

    // zstandard: 100,000 points of an ellipsoid, in one node.
    let ds = Dataset::open(&ept.join("ellipsoid-zstandard/ept.json")).unwrap();
    let (sums, bad) = dataset_sums(&ds);
    assert!(bad.is_empty());
    assert_eq!(sums.n, 100_000);
    // Colour survives (LAS 1.2 with colour, laszip).
    let ds = Dataset::open(&ept.join("1.2-with-color")).unwrap();
    let (sums, _) = dataset_sums(&ds);
    assert_eq!(sums.n, 1065);
    let root = ds.overview().unwrap();
    assert!(root.rgb.as_ref().unwrap().iter().any(|c| c[0] > 0));
    // binary, one point per node down one branch to 4-8-8-15.
    let ds = Dataset::open(&ept.join("bcbf")).unwrap();
    let (nodes, _) = ds.nodes();
    let deepest = nodes.iter().map(|n| n.key).max_by_key(|k| k.level).unwrap();
    assert_eq!(
        deepest,
        NodeKey {
            level: 4,
            cell: [8, 8, 15]
        }
    );
    for e in &nodes {
        assert_eq!(ds.read_node(e).unwrap().positions, vec![[1.0, 1.0, 999.0]]);
    }
    // One damaged node file: named, and every other node reads.
    let ds = Dataset::open(&ept.join("lone-star-invalid-tile")).unwrap();
    let (sums, bad) = dataset_sums(&ds);
    assert_eq!(bad.len(), 1, "{bad:?}");
    assert_eq!(
        bad[0].0,
        NodeKey {
            level: 2,
            cell: [2, 2, 2]
        }
    );
    assert!(bad[0].1.contains("ept-data/2-2-2-2.laz"), "{}", bad[0].1);
    let (nodes, _) = ds.nodes();
    let lost = nodes.iter().find(|n| n.key == bad[0].0).unwrap().points as u64;
    assert_eq!(sums.n, 518_862 - lost);
}

/// A missing EPT node file is a hole named by its node, not a failure of the dataset.
#[test]
fn a_missing_ept_node_is_a_named_hole() {
    let Some(src) = shared("ept/1.2-with-color") else {
        return;
    };
    let d = tempdir("missing");
    for sub in ["ept-hierarchy", "ept-data"] {
        std::fs::create_dir_all(d.join(sub)).unwrap();
    }
    std::fs::copy(src.join("ept.json"), d.join("ept.json")).unwrap();
    std::fs::copy(
        src.join("ept-hierarchy/0-0-0-0.json"),
        d.join("ept-hierarchy/0-0-0-0.json"),
    )
    .unwrap();
    let ds = Dataset::open(&d).unwrap();
    let (nodes, damage) = ds.nodes();
    assert!(damage.is_empty());
    let e = ds.read_node(&nodes[0]).unwrap_err();
    assert!(e.message.contains("0-0-0-0.laz"), "{}", e.message);
    assert_eq!(e.key, NodeKey::ROOT);
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn a_damaged_copc_chunk_or_page_is_named_and_the_rest_reads() {
    let Some(src) = shared("data/PDAL__copc_lone-star.copc.laz") else {
        return;
    };
    let d = tempdir("damaged");
    let ds = Dataset::open(&src).unwrap();
    let (nodes, _) = ds.nodes();
    let victim = nodes
        .iter()
        .filter(|n| n.points > 0)
        .nth(3)
        .unwrap()
        .clone();
    let mut bytes = std::fs::read(&src).unwrap();
    // The chunk's layer sizes (after the first point and its count) claim far more than it has.
    let at = victim.page.offset as usize + 30 + 4;
    bytes[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    let bad = d.join("bad.copc.laz");
    std::fs::write(&bad, &bytes).unwrap();
    let ds = Dataset::open(&bad).unwrap();
    let (sums, hurt) = dataset_sums(&ds);
    assert_eq!(hurt.len(), 1, "{hurt:?}");
    assert_eq!(hurt[0].0, victim.key);
    assert!(hurt[0].1.contains("layers claim"), "{}", hurt[0].1);
    assert_eq!(sums.n, 518_862 - victim.points as u64);

    // A root hierarchy page whose first entry's key is no node: the page is named.
    let info = 375 + 54;
    let root_at = u64::from_le_bytes(bytes[info + 40..info + 48].try_into().unwrap()) as usize;
    let mut bytes = std::fs::read(&src).unwrap();
    bytes[root_at..root_at + 4].copy_from_slice(&99i32.to_le_bytes());
    std::fs::write(&bad, &bytes).unwrap();
    let ds = Dataset::open(&bad).unwrap();
    let d2 = ds.hierarchy_page(&ds.root_page()).unwrap_err();
    assert!(d2.subtree && d2.message.contains("is not a node"), "{d2:?}");
    assert_eq!(d2.offset, root_at as u64);
    std::fs::remove_dir_all(&d).unwrap();
}

/// PotreeConverter's output, DEFAULT and BROTLI: the same points as the LAS file it was made
/// from, and the same nodes in both encodings.
#[test]
fn potree_2_from_potreeconverter() {
    let (Some(conv), Some(las)) = (
        shared("peers/potreeconverter/PotreeConverter"),
        shared("data/PDAL__las_autzen_trim.las"),
    ) else {
        return;
    };
    let d = tempdir("potree");
    let mut sets = Vec::new();
    for enc in ["DEFAULT", "BROTLI"] {
        let out = d.join(enc);
        let r = std::process::Command::new(&conv)
            .args([
                las.as_os_str(),
                "-o".as_ref(),
                out.as_os_str(),
                "--encoding".as_ref(),
                enc.as_ref(),
            ])
            .output()
            .unwrap();
        if !r.status.success() {
            eprintln!(
                "SKIPPED: PotreeConverter failed: {}",
                String::from_utf8_lossy(&r.stderr)
            );
            return;
        }
        let ds = Dataset::open(&out).unwrap();
        assert_eq!(ds.foreign_format(), Some("Potree 2.0"));
        let (sums, bad) = dataset_sums(&ds);
        assert!(bad.is_empty(), "{enc}: {bad:?}");
        // PotreeConverter rounds onto its own 0.01 grid: within a step a point on average.
        assert!(sums.close_to(&scan_sums(&las), 0.01), "{enc}: {sums:?}");
        let (nodes, _) = ds.nodes();
        let batches: Vec<PointBatch> = nodes.iter().map(|n| ds.read_node(n).unwrap()).collect();
        sets.push((nodes.len(), batches));
    }
    // Every point's colour and class, in each encoding (PotreeConverter's threads pick nodes'
    // samples differently from run to run, and it rounds positions onto its grid differently
    // in the two encodings, by one step: positions are checked against the LAS file above).
    let all = |batches: &Vec<PointBatch>| {
        let mut v: Vec<_> = batches
            .iter()
            .flat_map(|b| {
                (0..b.len()).map(move |i| {
                    (
                        b.rgb.as_ref().unwrap()[i],
                        b.classification.as_ref().unwrap()[i],
                    )
                })
            })
            .collect();
        v.sort();
        v
    };
    let (a, b) = (all(&sets[0].1), all(&sets[1].1));
    assert_eq!(a.len(), 110_000);
    let first = a.iter().zip(&b).find(|(x, y)| x != y);
    assert!(first.is_none(), "DEFAULT and BROTLI differ: {first:?}");
    assert!(a.iter().any(|x| x.0[0] > 0));
    std::fs::remove_dir_all(&d).unwrap();
}

/// A small HTTP/1.1 file server on 127.0.0.1: answers ranges (206) or, with `ranges` false,
/// the whole file (200, as a server without range support does); counts requests.
struct Server {
    base: String,
    requests: std::sync::Arc<std::sync::atomic::AtomicU64>,
}

fn serve(root: PathBuf, ranges: bool) -> Server {
    let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let base = format!("http://{}", l.local_addr().unwrap());
    let requests = std::sync::Arc::new(std::sync::atomic::AtomicU64::new(0));
    let count = requests.clone();
    std::thread::spawn(move || {
        for c in l.incoming() {
            let Ok(mut c) = c else { continue };
            count.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            let root = root.clone();
            std::thread::spawn(move || {
                let mut r = BufReader::new(c.try_clone().unwrap());
                let mut line = String::new();
                r.read_line(&mut line).unwrap();
                let path = line.split(' ').nth(1).unwrap_or("/").to_string();
                let mut range = None;
                loop {
                    let mut h = String::new();
                    if r.read_line(&mut h).unwrap_or(0) == 0 || h.trim().is_empty() {
                        break;
                    }
                    if let Some(v) = h.to_ascii_lowercase().strip_prefix("range: bytes=") {
                        let (a, b) = v.trim().split_once('-').unwrap();
                        range = Some((a.parse::<u64>().unwrap(), b.parse::<u64>().unwrap()));
                    }
                }
                let Ok(body) = std::fs::read(root.join(path.trim_start_matches('/'))) else {
                    let _ = c.write_all(
                        b"HTTP/1.1 404 Not Found\r\nContent-Length: 0\r\nConnection: close\r\n\r\n",
                    );
                    return;
                };
                let len = body.len() as u64;
                match range.filter(|_| ranges) {
                    Some((a, b)) if a < len => {
                        let b = b.min(len - 1);
                        let head = format!(
                            "HTTP/1.1 206 Partial Content\r\nContent-Length: {}\r\nContent-Range: bytes {a}-{b}/{len}\r\nConnection: close\r\n\r\n",
                            b - a + 1
                        );
                        let _ = c.write_all(head.as_bytes());
                        let _ = c.write_all(&body[a as usize..=b as usize]);
                    }
                    _ => {
                        let head = format!(
                            "HTTP/1.1 200 OK\r\nContent-Length: {len}\r\nConnection: close\r\n\r\n"
                        );
                        let _ = c.write_all(head.as_bytes());
                        let _ = c.write_all(&body);
                    }
                }
                let _ = r.read(&mut [0u8; 1]);
            });
        }
    });
    Server { base, requests }
}

#[test]
fn over_http_a_copc_shows_in_three_requests_and_ept_reads_as_on_disk() {
    let Some(data) = shared("data") else {
        return;
    };
    let server = serve(data.clone(), true);
    let url = format!("{}/PDAL__copc_lone-star.copc.laz", server.base);
    let ds = Dataset::open(Path::new(&url)).unwrap();
    // The first image: the header and VLRs, the root hierarchy page, the root chunk.
    let page = ds.hierarchy_page(&ds.root_page()).unwrap();
    let root = page.nodes.iter().find(|n| n.key == NodeKey::ROOT).unwrap();
    let points = ds.read_node(root).unwrap();
    let (requests, bytes) = ds.fetched().unwrap();
    assert_eq!(requests, 3, "requests to the first image");
    assert_eq!(
        server.requests.load(std::sync::atomic::Ordering::Relaxed),
        3
    );
    let file = std::fs::metadata(data.join("PDAL__copc_lone-star.copc.laz"))
        .unwrap()
        .len();
    assert!(bytes < file / 2, "{bytes} bytes of a {file}-byte file");
    assert_eq!(points.len(), root.points as usize);
    // Every node over HTTP is the node on disk.
    let local = Dataset::open(&data.join("PDAL__copc_lone-star.copc.laz")).unwrap();
    let (a, _) = dataset_sums(&ds);
    let (b, _) = dataset_sums(&local);
    assert_eq!(a, b);

    // A COPC file at a URL not named .copc.laz is told by its header.
    if let Some(ept) = shared("ept") {
        let server = serve(ept, true);
        let ds = Dataset::open(Path::new(&format!(
            "{}/lone-star-laszip/ept.json",
            server.base
        )))
        .unwrap();
        let (a, bad) = dataset_sums(&ds);
        assert!(bad.is_empty());
        assert_eq!(a.n, 518_862);
        assert!(ds.fetched().unwrap().0 > 0);
    }

    // A server that answers a range with the whole file is refused at the first request, in
    // one line that says why.
    let whole = serve(data, false);
    let e = Dataset::open(Path::new(&format!(
        "{}/PDAL__copc_lone-star.copc.laz",
        whole.base
    )))
    .err()
    .unwrap()
    .to_string();
    assert!(e.contains("ignores Range requests"), "{e}");
    assert!(!e.contains('\n'));
}
