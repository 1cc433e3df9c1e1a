//! Normals turned towards the scanners that saw the points: `synth --scene indoor -o X.e57`
//! writes one posed scan per station; `convert --structure mwkd` turns the normals it estimates
//! towards their scan's station, and `render` then leaves out the nodes that face away (the
//! normal cones of Goswami et al. 2010), where normals turned up could not.

mod common;
use common::*;

/// Points and nodes `render` drew.
fn drawn(out: &str) -> (u64, u64) {
    let line = out.lines().find(|l| l.contains(" points in ")).expect(out);
    let n = |key: &str| -> u64 {
        let before = &line[..line.find(key).unwrap()];
        before
            .split_whitespace()
            .last()
            .unwrap()
            .replace(',', "")
            .parse()
            .unwrap()
    };
    (n(" points in "), n(" nodes"))
}

#[test]
fn normals_face_their_scanners_and_nodes_facing_away_are_culled() {
    let d = tempdir("scanners");
    // Two scans of the first room (its stations differ with the seed), as E57 and as LAS.
    let (a, b, las) = (d.join("a.e57"), d.join("b.e57"), d.join("a.las"));
    for (path, seed) in [(&a, "1"), (&b, "2"), (&las, "1")] {
        ok(&[
            "synth",
            "--scene",
            "indoor",
            "--points",
            "120k",
            "--seed",
            seed,
            "-o",
            s(path),
        ]);
    }
    let r = myriad(&["info", s(&a)]);
    assert!(r.stdout.contains("1 scan"), "{}", r.stdout);
    let (oriented, up, both) = (d.join("o.myr"), d.join("u.myr"), d.join("both.myr"));
    for (inputs, out) in [
        (vec![s(&a)], &oriented),
        (vec![s(&las)], &up),
        (vec![s(&a), s(&b)], &both),
    ] {
        let mut args = vec!["convert"];
        args.extend(inputs);
        args.extend(["-o", s(out), "--structure", "mwkd", "--capacity", "4096"]);
        ok(&args);
    }
    let info = |p: &std::path::Path| ok(&["info", s(p)]);
    assert!(info(&oriented).contains("oriented"), "{}", info(&oriented));
    assert!(!info(&up).contains("oriented"), "{}", info(&up));
    // The second file's scan is the dataset's second: its points' source IDs moved up.
    assert!(info(&both).contains("oriented"));
    let back = d.join("both.las");
    ok(&["extract", s(&both), "-o", s(&back)]);
    let mut src = myriad_io::open(&back, &myriad_io::OpenOptions::default()).unwrap();
    let mut ids = std::collections::BTreeMap::new();
    while let Some(b) = src.read_batch(myriad_io::DEFAULT_BATCH).unwrap() {
        for id in b.point_source_id.unwrap() {
            *ids.entry(id).or_insert(0u64) += 1;
        }
    }
    assert_eq!(
        ids.into_iter().collect::<Vec<_>>(),
        vec![(1, 120_000), (2, 120_000)]
    );
    // The room is 12 x 8 x 3 m at the scenes' origin (500000, 4400000, 0).
    let render = |ds: &std::path::Path, camera: &str| {
        let png = d.join("r.png");
        let out = ok(&[
            "render",
            s(ds),
            "-o",
            s(&png),
            "--camera",
            camera,
            "--width",
            "200",
            "--height",
            "150",
            "--budget",
            "10M",
            "--raster",
            "cpu",
            "--force",
        ]);
        drawn(&out)
    };
    // Behind the south wall, looking north through it: its inside faces away and is left out.
    let behind = "500006,4399994,1.5,500006,4400004,1.5";
    let (o, u) = (render(&oriented, behind), render(&up, behind));
    // Inside, at the room's middle looking north: everything faces the stations.
    let inside = "500006,4400001,1.5,500006,4400008,1.5";
    let (oi, ui) = (render(&oriented, inside), render(&up, inside));
    eprintln!("behind: oriented {o:?}, up {u:?}; inside: oriented {oi:?}, up {ui:?}");
    // The same points (one scan, as E57 and as LAS): behind the wall the oriented dataset
    // draws fewer; inside, where nothing faces away, as many.
    assert!((o.0 as f64) < 0.95 * u.0 as f64, "behind: {o:?} {u:?}");
    assert!(oi.0 as f64 > 0.97 * ui.0 as f64, "inside: {oi:?} {ui:?}");
}

/// Airborne scans: each flight line's scan angles say which side its points were seen from
/// (`myriad_build::sides`), so `mwkd` turns the normals it estimates that way ("oriented") and
/// normal cones leave out what faces away (roofs seen from below), and nothing from a view
/// above, where everything faces the camera: there the image is `--normal-cones off`'s.
#[test]
fn airborne_normals_face_their_flight_lines_and_what_faces_away_is_culled() {
    use myriad_io::PointSource;
    use myriad_io::las::{LasSink, LasSource, LasWriteOptions};
    let d = tempdir("flights");
    let las = d.join("city.las");
    ok(&["synth", "--points", "400k", "-o", s(&las)]);
    // The same points with every scan angle 0: no side to go on, normals turned up.
    let flat = d.join("flat.las");
    let mut src = LasSource::open(&las).unwrap();
    let mut sink = LasSink::create(&flat, LasWriteOptions::like(src.header()), true).unwrap();
    while let Some(mut b) = src.read_batch(100_000).unwrap() {
        b.scan_angle.as_mut().unwrap().fill(0.0);
        sink.write(&b).unwrap();
    }
    sink.finish().unwrap();
    let (oriented, up) = (d.join("o.myr"), d.join("u.myr"));
    for (input, out) in [(&las, &oriented), (&flat, &up)] {
        ok(&[
            "convert",
            s(input),
            "-o",
            s(out),
            "--structure",
            "mwkd",
            "--capacity",
            "4096",
        ]);
    }
    assert!(ok(&["info", s(&oriented)]).contains("oriented"));
    assert!(!ok(&["info", s(&up)]).contains("oriented"));
    let render = |ds: &std::path::Path, png: &std::path::Path, cones: &str, camera: &str| {
        drawn(&ok(&[
            "render",
            s(ds),
            "-o",
            s(png),
            "--camera",
            camera,
            "--width",
            "240",
            "--height",
            "160",
            "--budget",
            "10M",
            "--raster",
            "cpu",
            "--force",
            "--normal-cones",
            cones,
        ]))
    };
    // Above the city's south edge looking north down into its streets, and at street level
    // looking up, where roofs are seen from below: the backs of what the aircraft saw.
    for (view, camera) in [
        ("oblique", "500000,4399900,60,500000,4400040,0"),
        ("street", "500000,4399990,3,500000,4400060,8"),
    ] {
        let (po, pa) = (d.join("o.png"), d.join("all.png"));
        let on = render(&oriented, &po, "on", camera);
        let off = render(&oriented, &pa, "off", camera);
        // Turned up, the normals have no sign: nothing is culled, with or without cones.
        let pu = d.join("u.png");
        assert_eq!(
            render(&up, &pu, "on", camera),
            render(&up, &pu, "off", camera)
        );
        let (a, b) = (decode_png(&po).2, decode_png(&pa).2);
        let differ = a
            .chunks_exact(4)
            .zip(b.chunks_exact(4))
            .filter(|(x, y)| (0..3).any(|k| (x[k] as i32 - y[k] as i32).abs() > 24))
            .count();
        eprintln!(
            "{view}: cones on {on:?}, off {off:?}; {differ} of {} pixels differ",
            a.len() / 4
        );
        if view == "oblique" {
            // From above, every node holds something facing up: nothing culled, nothing lost.
            assert_eq!(on, off);
            assert_eq!(differ, 0);
        } else {
            // From below, roofs (seen from the air, so facing up) face away: left out.
            assert!(
                (on.0 as f64) < 0.97 * off.0 as f64,
                "{view}: {on:?} {off:?}"
            );
        }
    }
}
