//! `tissuefit render`: a known tissue drawn to a PNG of the asked size, its pixels where the tissue
//! is, the colourings and views distinct; bad input an error naming the problem (exit 2).

use crate::support::cli::tissuefit;
use std::path::{Path, PathBuf};

fn quartet() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/demo/cell_quartet.vtk")
}

fn render(out: &Path, extra: &[&str]) -> image::RgbImage {
    let tissue = quartet();
    let mut args = vec!["render", tissue.to_str().unwrap(), "--out", out.to_str().unwrap()];
    args.extend_from_slice(extra);
    let o = tissuefit(&args);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    image::open(out).expect("a PNG").to_rgb8()
}

/// The bounding box (x0, y0, x1, y1) of the non-white pixels and their count.
fn drawn(img: &image::RgbImage) -> ([u32; 4], usize) {
    let (mut b, mut n) = ([u32::MAX, u32::MAX, 0, 0], 0);
    for (x, y, p) in img.enumerate_pixels() {
        if p.0 != [255, 255, 255] {
            n += 1;
            b = [b[0].min(x), b[1].min(y), b[2].max(x), b[3].max(y)];
        }
    }
    (b, n)
}

#[test]
fn a_tissue_is_drawn_centred_at_the_asked_size() {
    let tmp = tempfile::tempdir().unwrap();
    let img = render(&tmp.path().join("iso.png"), &["--size", "320,240"]);
    assert_eq!(img.dimensions(), (320, 240));
    let ([x0, y0, x1, y1], n) = drawn(&img);
    // Fitted into the frame with a 6 % margin: the drawing spans most of one side, touches no border,
    // and is centred.
    assert!(x0 >= 10 && y0 >= 10 && x1 <= 310 && y1 <= 230, "box {x0},{y0}–{x1},{y1}");
    assert!(x1 - x0 >= 250 || y1 - y0 >= 190, "box {x0},{y0}–{x1},{y1} fills the frame");
    assert!(((x0 + x1) as i64 - 320).abs() <= 4 && ((y0 + y1) as i64 - 240).abs() <= 4, "centred");
    assert!(n > 320 * 240 / 5, "{n} pixels drawn");
    // Four cells coloured by id: at least four distinct saturated colours.
    let mut hues = std::collections::BTreeSet::new();
    for p in img.pixels() {
        let [r, g, b] = p.0;
        if p.0 != [255, 255, 255] && r.max(g).max(b) - r.min(g).min(b) > 60 {
            hues.insert((r / 32, g / 32, b / 32));
        }
    }
    assert!(hues.len() >= 4, "{hues:?}");
}

#[test]
fn views_colourings_and_edges_change_the_picture() {
    let tmp = tempfile::tempdir().unwrap();
    let base = render(&tmp.path().join("a.png"), &["--size", "200,200", "--view", "z"]);
    let x = render(&tmp.path().join("b.png"), &["--size", "200,200", "--view", "x"]);
    let kind = render(&tmp.path().join("c.png"), &["--size", "200,200", "--view", "z", "--color-by", "kind"]);
    let edges = render(&tmp.path().join("d.png"), &["--size", "200,200", "--view", "z", "--edges"]);
    assert_ne!(base, x);
    assert_ne!(base, kind);
    // Edges only darken: never a lighter pixel, and many darker ones.
    let sum = |p: &image::Rgb<u8>| p.0.iter().map(|&v| v as u32).sum::<u32>();
    let darker = base.pixels().zip(edges.pixels()).filter(|(a, b)| sum(b) < sum(a)).count();
    let lighter = base.pixels().zip(edges.pixels()).filter(|(a, b)| (0..3).any(|i| b.0[i] > a.0[i])).count();
    assert!(darker > 500 && lighter == 0, "darker {darker}, lighter {lighter}");
    // Same silhouette whatever the colouring.
    assert_eq!(drawn(&base).0, drawn(&kind).0);
}

#[test]
fn bad_input_is_an_error_naming_the_problem() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("v.png");
    let out = out.to_str().unwrap();
    let quartet = quartet();
    let quartet = quartet.to_str().unwrap();
    let cases: [(Vec<&str>, &str); 4] = [
        (vec!["render", "missing.vtk", "--out", out], "missing.vtk"),
        (vec!["render", quartet, "--out", "v.jpg"], "PNG"),
        (vec!["render", quartet, "--out", out, "--size", "0,100"], "between 16 and 8192"),
        (vec!["render", quartet, "--out", out, "--size", "big"], "W,H"),
    ];
    for (args, needle) in cases {
        let o = tissuefit(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
    }
    assert!(!tmp.path().join("v.png").exists());
}

/// `tissuefit tensions` writes its map picture (tensions.png); `render --color-by tension|pressure`
/// draws the map of its tensions.vtp with a colour bar, on the viridis scale: exploded, hetero4's six
/// different interface tensions show as distinct colours, all of them on the scale (or the grey of
/// faces without a value). Asking for an array the file lacks names those it has.
#[test]
fn tension_and_pressure_maps_are_drawn_from_tensions_vtp() {
    let tmp = tempfile::tempdir().unwrap();
    let cluster = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("validation/evolver/fixtures/hetero4/cluster.vtk");
    let out = tmp.path().join("t");
    let o = tissuefit(&["tensions", cluster.to_str().unwrap(), "--length-unit", "um", "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stage_png = image::open(out.join("tensions.png")).expect("tensions.png").to_rgb8();
    assert_eq!(stage_png.dimensions(), (900, 700));
    let vtp = out.join("tensions.vtp");
    let png = tmp.path().join("map.png");
    let args = |by: &str| {
        vec![
            "render".to_owned(),
            vtp.to_str().unwrap().to_owned(),
            "--out".into(),
            png.to_str().unwrap().into(),
            "--color-by".into(),
            by.into(),
            "--size".into(),
            "500,400".into(),
            "--explode".into(),
            "0.6".into(),
        ]
    };
    let o = tissuefit(&args("tension").iter().map(String::as_str).collect::<Vec<_>>());
    let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout.contains("coloured by tension (relative to the gauge)"), "{stdout}");
    let img = image::open(&png).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (500, 400));
    // Every drawn pixel of the tissue (left of the bar strip) is a shaded viridis colour or grey:
    // scaled back to full brightness it lies near one of the scale's samples.
    let strip = (500 / 5).clamp(70, 180);
    let scale: Vec<[f64; 3]> = (0..=64).map(|k| tissuefit::render::viridis(k as f64 / 64.0)).collect();
    let mut positions = std::collections::BTreeSet::new();
    let mut off = 0;
    for (_, _, p) in img.enumerate_pixels().filter(|(x, _, p)| *x < 500 - strip && p.0 != [255, 255, 255]) {
        let c = p.0.map(|v| v as f64 / 255.0);
        if (c[0] - c[1]).abs() < 0.02 && (c[1] - c[2]).abs() < 0.02 {
            continue; // grey: no value, or an anti-aliased edge against the white background
        }
        // Shading multiplies by 0.6–1.0; find the scale sample and brightness that fit best.
        let best = scale
            .iter()
            .enumerate()
            .map(|(k, s)| {
                let f = (c[0] * s[0] + c[1] * s[1] + c[2] * s[2]) / (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
                (k, (0..3).map(|i| (c[i] - f * s[i]).powi(2)).sum::<f64>().sqrt())
            })
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap();
        if best.1 < 0.04 {
            positions.insert(best.0 / 4);
        } else {
            off += 1;
        }
    }
    assert!(positions.len() >= 4, "distinct scale positions: {positions:?}");
    // Off-scale pixels are only the box-filtered outlines between faces of different colours.
    assert!(off < 500 * 400 / 20, "{off} pixels off the scale");
    let o = tissuefit(&args("pressure").iter().map(String::as_str).collect::<Vec<_>>());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    let mut missing = args("field");
    missing.extend(["--field".into(), "stress".into()]);
    let o = tissuefit(&missing.iter().map(String::as_str).collect::<Vec<_>>());
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("stress") && err.contains("tension") && err.contains("pressure"), "{err}");
    let o = tissuefit(&args("field").iter().map(String::as_str).collect::<Vec<_>>());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--field NAME"));
    let o = tissuefit(&["render", cluster.to_str().unwrap(), "--out", png.to_str().unwrap(), "--color-by", "tension"]);
    assert!(String::from_utf8_lossy(&o.stderr).contains(".vtp"), "{}", String::from_utf8_lossy(&o.stderr));
}
