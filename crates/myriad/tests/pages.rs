//! Hierarchy pages read on demand (issue 22), as a user meets it: `info` takes its per-level
//! table from the metadata, `extract --box` reads only the pages its box meets, `verify` reads
//! them all, `render` reads what the view reaches.

mod common;
use common::{myriad, s, synth, tempdir};
use std::path::Path;

/// Opening reads the root hierarchy page alone (issue 22): `info` takes its per-level table
/// from the metadata, so a damaged page deep in the hierarchy goes unnoticed there; `verify`
/// reads every page and names it; `render` draws around it and warns once it reaches it.
#[test]
fn info_reads_the_metadata_and_render_reads_hierarchy_pages_on_demand() {
    let d = tempdir("pages");
    let las = synth(&d, "p.las", 200_000);
    let out = d.join("p.myr");
    let r = myriad(&["convert", s(&las), "-o", s(&out), "--capacity", "300"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let info = |path: &Path| {
        let r = myriad(&["info", "--json", s(path)]);
        assert_eq!(r.code, 0, "{}", r.stderr);
        (
            serde_json::from_str::<serde_json::Value>(r.stdout.trim()).unwrap(),
            r.stderr,
        )
    };
    let (v, _) = info(&out);
    let levels = v["levels"].as_array().unwrap().clone();
    let sum: u64 = levels.iter().map(|l| l["points"].as_u64().unwrap()).sum();
    assert_eq!(sum, 200_000);
    assert!(
        levels.len() > 5,
        "{} levels: one hierarchy page",
        levels.len()
    );
    // Not walked: no count of damaged pages.
    assert!(v["damaged_hierarchy_pages"].is_null());

    // Damage the first page below the root page.
    let ds = myriad_format::Dataset::open(&out).unwrap();
    let root = ds.hierarchy_page(&ds.root_page()).unwrap();
    let below = root.children.first().expect("a page below the root page");
    let mut bytes = std::fs::read(&out).unwrap();
    bytes[below.page.offset as usize + 20] ^= 0x55;
    std::fs::write(&out, &bytes).unwrap();

    let (v, stderr) = info(&out);
    assert_eq!(v["levels"].as_array().unwrap(), &levels);
    assert!(stderr.is_empty(), "{stderr}");
    let r = myriad(&["verify", s(&out)]);
    assert_eq!(r.code, 1, "{}", r.stdout);
    assert!(
        r.stdout
            .contains(&format!("hierarchy page of subtree {}", below.key)),
        "{}",
        r.stdout
    );
    // A box away from the damaged page's subtree reads none of its pages; one inside it meets
    // the damage.
    let root = &v["root"];
    let side = (root["max"][0].as_f64().unwrap() - root["min"][0].as_f64().unwrap())
        / (1u64 << below.key.level) as f64;
    let cube_box = |cell: [u32; 3]| {
        let lo: Vec<f64> = (0..3)
            .map(|a| root["min"][a].as_f64().unwrap() + (cell[a] as f64 + 0.1) * side)
            .collect();
        let hi: Vec<f64> = lo.iter().map(|l| l + 0.8 * side).collect();
        format!(
            "{},{},{},{},{},{}",
            lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]
        )
    };
    let c = below.key.cell;
    let part = d.join("part.las");
    let r = myriad(&[
        "extract",
        s(&out),
        "-o",
        s(&part),
        "--box",
        &cube_box([c[0] ^ 1, c[1], c[2]]),
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(!r.stderr.contains("warning"), "{}", r.stderr);
    let r = myriad(&[
        "extract",
        s(&out),
        "-o",
        s(&part),
        "--force",
        "--box",
        &cube_box(c),
    ]);
    assert_eq!(r.code, 1, "{}", r.stderr);
    assert!(
        r.stderr
            .contains(&format!("hierarchy page of subtree {}", below.key)),
        "{}",
        r.stderr
    );
    // Every node wanted: the page is reached, reported, and the rest drawn; the reference
    // image lacks points, so the command fails (issue 40).
    let png = d.join("p.png");
    let mut args = common::render_cpu(s(&out), s(&png), ("160", "120"));
    args.push("--full");
    let r = myriad(&args);
    assert_eq!(r.code, 1, "{}", r.stderr);
    assert!(r.stderr.contains("error: 1 damaged page"), "{}", r.stderr);
    assert!(
        r.stderr
            .contains(&format!("hierarchy page of subtree {}", below.key)),
        "{}",
        r.stderr
    );
    assert!(png.exists());
    std::fs::remove_dir_all(&d).unwrap();
}
