//! Positions quantized per node (issue 21) from file to pixels: a grid of points 1 cm apart at
//! UTM and at Earth-centred (ECEF) coordinates, converted into a dataset of many nodes, drawn
//! one pixel each from straight above at 4 pixels per centimetre, lands on exactly the pixels
//! the camera puts it (computed here in f64): no jitter, no crack where nodes meet.

mod common;

use common::{myriad, s, tempdir};

/// The lit pixels (red channel above 128) of a PNG.
fn lit(path: &std::path::Path) -> std::collections::BTreeSet<(usize, usize)> {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut img = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut img).unwrap();
    let channels = info.line_size / info.width as usize;
    (0..info.height as usize)
        .flat_map(|y| (0..info.width as usize).map(move |x| (x, y)))
        .filter(|&(x, y)| img[y * info.line_size + x * channels] > 128)
        .collect()
}

#[test]
fn grids_at_utm_and_ecef_coordinates_land_on_their_pixels() {
    let d = tempdir("coordinates");
    for (name, corner) in [
        ("utm", [5_170_845.29, 3_964_547.02, 452.07]),
        ("ecef", [6_378_137.0, 0.0, 0.0]),
        ("ecef-negative", [-2_694_045.0, -4_293_642.0, 3_857_878.0]),
    ] {
        // 96 x 96 points, white, in a text file; a small capacity makes many nodes.
        let xyz = d.join(format!("{name}.xyz"));
        let mut text = String::new();
        for i in 0..96 {
            for j in 0..96 {
                let p = [
                    corner[0] + i as f64 * 0.01,
                    corner[1] + j as f64 * 0.01,
                    corner[2],
                ];
                text += &format!("{:.3} {:.3} {:.3} 255 255 255\n", p[0], p[1], p[2]);
            }
        }
        std::fs::write(&xyz, text).unwrap();
        let ds = d.join(format!("{name}.myr"));
        let r = myriad(&["convert", s(&xyz), "-o", s(&ds), "--capacity", "1024"]);
        assert_eq!(r.code, 0, "{}", r.stderr);
        // Straight down with Y up: 4 px per cm at 512 x 512 and 60 degrees puts the eye 1/400 of
        // the focal length above; its centre an eighth of a pixel off the pixel borders.
        let focal = 256.0 / 30f64.to_radians().tan();
        let render = |dx: f64, png: &std::path::Path| {
            let c = [
                corner[0] + 0.475 + 0.125 / 400.0 + dx,
                corner[1] + 0.475 + 0.125 / 400.0,
            ];
            let camera = format!(
                "{:.7},{:.7},{:.7},{:.7},{:.7},{:.7}",
                c[0],
                c[1],
                corner[2] + focal / 400.0,
                c[0],
                c[1],
                corner[2]
            );
            let r = myriad(&[
                "render",
                s(&ds),
                "-o",
                s(png),
                "--force",
                "--camera",
                &camera,
                "--up",
                "0,1,0",
                "--fov",
                "60",
                "--width",
                "512",
                "--height",
                "512",
                "--point-size",
                "fixed:1",
                "--passes",
                "none",
                "--full",
                "--raster",
                "cpu",
            ]);
            assert_eq!(r.code, 0, "{name}: {}", r.stderr);
            r.stdout
        };
        let png = d.join(format!("{name}.png"));
        let out = render(0.0, &png);
        assert!(out.contains("9,216 points in"), "{name}: {out}");
        let nodes: usize = out
            .split(" nodes")
            .next()
            .and_then(|h| h.rsplit(' ').next())
            .and_then(|n| n.parse().ok())
            .unwrap();
        assert!(nodes > 4, "{name}: {nodes} nodes");
        // Point (i, j) at x = 256 + 4 (i - 47.5) - 1/8 and y = 256 - 4 (j - 47.5) + 1/8.
        let expected: std::collections::BTreeSet<(usize, usize)> = (0..96)
            .flat_map(|i| (0..96).map(move |j| (65 + 4 * i, 446 - 4 * j)))
            .collect();
        assert_eq!(lit(&png), expected, "{name}");
        // A hundredth of a pixel to the side: the same image.
        let moved = d.join(format!("{name}-moved.png"));
        render(0.01 / 400.0, &moved);
        assert_eq!(lit(&moved), expected, "{name}: jitter");
    }
}
