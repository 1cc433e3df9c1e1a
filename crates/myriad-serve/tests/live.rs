//! A dataset served while it is built (`myriad_serve::live`): `/build/NAME?since=V` names the
//! newest version and its nodes that are new against `V`; every other node of it is the same
//! page, byte for byte, as in `V` (what lets the web viewer keep it drawn), down to the finished
//! dataset; `focus` steers the build and is checked.

use myriad_build::convert::{ConvertOptions, Silent, convert};
use myriad_build::growing::Growing;
use myriad_format::Dataset;
use myriad_format::remote::HttpBytes;
use myriad_serve::{Catalog, Options, Server, live::Live};
use std::collections::{BTreeMap, BTreeSet};
use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("myriad-serve-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The status and body of a GET.
fn get(server: &Server, path: &str) -> (u16, String) {
    let mut s = TcpStream::connect(server.addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut out = Vec::new();
    let _ = s.read_to_end(&mut out);
    let text = String::from_utf8_lossy(&out).to_string();
    let status = text[9..12].parse().unwrap();
    let body = text
        .split_once("\r\n\r\n")
        .map_or("", |(_, b)| b)
        .to_string();
    (status, body)
}

/// Every node of a version, read over HTTP: its page bytes by key (`None`: the version is gone).
fn pages(server: &Server, version: &str) -> Option<BTreeMap<[u32; 4], Vec<u8>>> {
    let url = format!("http://{}/d/city.myr?v={version}", server.addr);
    let bytes = HttpBytes::open(&url).ok()?;
    let ds = Dataset::from_source(Arc::new(bytes), Path::new("city.myr")).ok()?;
    let (nodes, damage) = ds.nodes();
    if !damage.is_empty() {
        return None;
    }
    let mut out = BTreeMap::new();
    for e in nodes {
        let k = [e.key.level, e.key.cell[0], e.key.cell[1], e.key.cell[2]];
        out.insert(k, ds.node_page(&e).ok()?);
    }
    Some(out)
}

#[test]
fn a_viewer_is_told_which_nodes_are_new_and_keeps_the_others_byte_for_byte() {
    let d = dir("live");
    let las = d.join("city.las");
    let opts = myriad_synth::SynthOptions {
        points: 400_000,
        scene: myriad_synth::SceneKind::City,
        seed: 5,
    };
    myriad_synth::write(&opts, &las, true, |_| {}).unwrap();
    let preview = myriad_build::cached::preview_dataset(&las, &d).unwrap();
    let live = Live::new(&preview);
    let mut catalog = Catalog::new(&[]).unwrap();
    catalog
        .add_live("city.myr", live.clone(), &preview, &las)
        .unwrap();
    let server =
        Server::start(catalog, "127.0.0.1:0".parse().unwrap(), Options::default()).unwrap();

    // Bad questions first.
    assert_eq!(get(&server, "/build/none.myr").0, 404);
    assert_eq!(get(&server, "/build/city.myr?focus=1,2").0, 400);
    assert_eq!(get(&server, "/build/city.myr?focus=1,nan,2").0, 400);
    let (code, body) = get(&server, "/build/city.myr?since=");
    assert_eq!(code, 200, "{body}");
    let v: serde_json::Value = serde_json::from_str(&body).unwrap();
    assert_eq!(v["version"], "preview", "{v}");
    assert_eq!(v["building"], true, "{v}");

    // The build, a snapshot after each chunk, slowed so that a poll meets most of them.
    let out = d.join("city.myr");
    let g = Growing::new(Duration::ZERO);
    g.set_fill(myriad_build::cached::preview_batch(&las).unwrap());
    live.building(g.clone());
    // Where a viewer looks is where the build goes next.
    let b = myriad_build::cached::preview_batch(&las).unwrap();
    let p = b.positions[b.len() / 2];
    let (code, body) = get(
        &server,
        &format!("/build/city.myr?focus={},{},{}", p[0], p[1], p[2]),
    );
    assert_eq!(code, 200, "{body}");
    assert_eq!(g.focus(), Some(p));
    let build = {
        let (las, out, live) = (las.clone(), out.clone(), live.clone());
        std::thread::spawn(move || {
            let mut o = ConvertOptions::new(&out);
            o.memory = myriad_build::convert::MIN_MEMORY;
            o.chunk_points = Some(20_000);
            o.params.capacity = 4096;
            o.threads = 1;
            o.growing = Some(g);
            let r = convert(std::slice::from_ref(&las), &o, &Silent);
            live.ended(r.as_ref().ok().map(|_| out.clone()));
            r.map(|_| ())
        })
    };

    // A viewer's polls: each new version's pages against the last one's.
    let mut at = "preview".to_string();
    let mut before = pages(&server, "preview").unwrap();
    let (mut versions, mut kept, mut reloaded) = (0, 0, 0);
    loop {
        let (code, body) = get(&server, &format!("/build/city.myr?since={at}"));
        assert_eq!(code, 200, "{body}");
        let v: serde_json::Value = serde_json::from_str(&body).unwrap();
        let version = v["version"].as_str().unwrap().to_string();
        if version != at {
            let Some(now) = pages(&server, &version) else {
                // Gone already (a newer one came first): ask again from the one held.
                continue;
            };
            versions += 1;
            let new: Option<BTreeSet<[u32; 4]>> = v["new"].as_array().map(|a| {
                a.iter()
                    .map(|k| serde_json::from_value(k.clone()).unwrap())
                    .collect()
            });
            if at == "preview" {
                assert!(new.is_none(), "from the preview every node is new: {v}");
            }
            if let Some(new) = &new {
                for (k, page) in &now {
                    if !new.contains(k) {
                        assert_eq!(
                            before.get(k),
                            Some(page),
                            "{k:?} said unchanged from {at} to {version}"
                        );
                        kept += 1;
                    } else {
                        reloaded += 1;
                    }
                }
            }
            at = version;
            before = now;
        }
        if v["building"] == false {
            assert_eq!(at, "final", "{v}");
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    build.join().unwrap().unwrap();
    eprintln!("{versions} versions; nodes kept {kept}, loaded again {reloaded}");
    assert!(versions >= 3, "{versions} versions seen");
    assert!(
        kept > 0 && reloaded > 0,
        "{kept} nodes kept, {reloaded} loaded again"
    );
    // The finished dataset is the file the build wrote.
    let finished = Dataset::open(&out).unwrap();
    assert_eq!(finished.nodes().0.len(), before.len());
    drop(server);
    let _ = std::fs::remove_dir_all(&d);
}
