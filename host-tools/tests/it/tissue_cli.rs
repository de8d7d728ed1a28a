//! `softjoint tissue field|compress`: outputs on small inputs, and named
//! refusals of bad volumes, bad scenarios and bad flags.
use crate::common;

use common::{file, ok, refused, s, scratch, softjoint, stdout};
use plant_tissue::field::volume::Volume;

#[test]
fn field_on_a_small_twin_writes_tables_a_picture_and_errors_against_the_truth() {
    let dir = scratch("tissue-field");
    let out = dir.join("out");
    let o = softjoint(&[
        "tissue",
        "field",
        "--synthetic",
        "--dims",
        "80x80x20",
        "--features-initial",
        "120",
        "--features-deformed",
        "500",
        "--matching",
        "all",
        "--write-volumes",
        "--out-dir",
        s(&out),
        "--json",
    ]);
    ok(&o);
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).expect("JSON summary");
    assert_eq!(v["variants"].as_array().unwrap().len(), 3);
    assert_eq!(v["variants"][0]["matching"], "direction");
    assert!(v["variants"][0]["matches"].as_u64().unwrap() >= 20, "{v}");
    assert!(
        v["against_truth"]["variants"][0]["dense_endpoint_rms_mm"]
            .as_f64()
            .unwrap()
            < 2.0
    );
    for f in [
        "matches.csv",
        "field.csv",
        "mid_slice.svg",
        "summary.json",
        "initial.nii.gz",
        "deformed.nii.gz",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    // --matching all: a dense field per matching (field.csv for the
    // first only before), and the summary lists every file written
    // (--write-volumes' two were not listed).
    let files: Vec<&str> = v["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f.as_str().unwrap())
        .collect();
    assert_eq!(
        files,
        [
            "initial.nii.gz",
            "deformed.nii.gz",
            "matches.csv",
            "field.csv",
            "field_strength.csv",
            "field_as-printed.csv",
            "mid_slice.svg",
            "summary.json"
        ]
    );
    for (f, name) in [
        ("field.csv", "direction"),
        ("field_strength.csv", "strength"),
        ("field_as-printed.csv", "as-printed"),
    ] {
        let text = std::fs::read_to_string(out.join(f)).unwrap();
        assert!(
            text.starts_with(&format!("# dense field of `{name}` matching")),
            "{f}"
        );
    }
    let csv = std::fs::read_to_string(out.join("matches.csv")).unwrap();
    assert!(csv
        .starts_with("matching,x_mm,y_mm,z_mm,dx_mm,dy_mm,dz_mm,correlation,strength,true_dx_mm"));
    assert!(!csv.contains("NaN") && !csv.contains("inf"));
    let svg = std::fs::read_to_string(out.join("mid_slice.svg")).unwrap();
    assert!(svg.contains("measured field") && svg.contains("<path"));
    // The written pair reads back and measures as files.
    let back = Volume::read_nifti(&out.join("initial.nii.gz")).unwrap();
    assert_eq!(back.dims(), [80, 80, 20]);
    let again = dir.join("again");
    let o = softjoint(&[
        "tissue",
        "field",
        s(&out.join("initial.nii.gz")),
        s(&out.join("deformed.nii.gz")),
        "--features-initial",
        "120",
        "--features-deformed",
        "500",
        "--out-dir",
        s(&again),
    ]);
    ok(&o);
    assert!(stdout(&o).contains("direction"), "{}", stdout(&o));
}

#[test]
fn bad_volumes_are_refused_by_name() {
    let dir = scratch("tissue-bad-volumes");
    let out = dir.join("out");
    let a = Volume::new([20, 20, 8], [1.0; 3], vec![1.0; 3200], "a").unwrap();
    let b = Volume::new([20, 18, 8], [1.0; 3], vec![1.0; 2880], "b").unwrap();
    let pa = dir.join("a.nii");
    let pb = dir.join("b.nii");
    a.write_nifti(&pa).unwrap();
    b.write_nifti(&pb).unwrap();
    refused(
        &["tissue", "field", s(&pa), s(&pb), "--out-dir", s(&out)],
        &["deformed volume", "20×18×8", "20×20×8"],
    );
    // A NaN voxel: written by hand as a NIfTI file with the crate.
    let mut data = vec![1.0f32; 3200];
    data[20 * 20 * 3 + 20 * 5 + 7] = f32::NAN;
    let arr = ndarray_of(&data, [20, 20, 8]);
    let pn = dir.join("nan.nii");
    nifti::writer::WriterOptions::new(&pn)
        .write_nifti(&arr)
        .unwrap();
    refused(
        &["tissue", "field", s(&pn), s(&pa), "--out-dir", s(&out)],
        &["nan.nii", "voxel (7, 5, 3) is not a finite number"],
    );
    let junk = file(&dir, "junk.nii", "not a volume");
    refused(
        &["tissue", "field", &junk, s(&pa), "--out-dir", s(&out)],
        &["junk.nii"],
    );
    refused(
        &["tissue", "field", "--out-dir", s(&out)],
        &["give two volumes"],
    );
    // Flag errors are clap's (exit 2), with our reason.
    for (dims, needle) in [
        ("80x80", "NXxNYxNZ"),
        ("80x80x4", "16 to 1024"),
        ("80xtwox20", "`two` is not"),
    ] {
        let o = softjoint(&[
            "tissue",
            "field",
            "--synthetic",
            "--dims",
            dims,
            "--out-dir",
            s(&out),
        ]);
        assert_eq!(o.status.code(), Some(2));
        assert!(
            common::stderr(&o).contains(needle),
            "{}",
            common::stderr(&o)
        );
    }
}

fn ndarray_of(data: &[f32], d: [usize; 3]) -> ndarray::Array3<f32> {
    use ndarray::ShapeBuilder;
    ndarray::Array3::from_shape_vec((d[0], d[1], d[2]).f(), data.to_vec()).unwrap()
}

#[test]
fn compress_writes_markers_and_pictures_and_reports_the_facts() {
    let dir = scratch("tissue-compress");
    let scenario = file(
        &dir,
        "coarse.toml",
        "# a coarse, quick phantom\nmesh_divisions = 3\nstep_mm = 5.0\n",
    );
    let out = dir.join("out");
    let o = softjoint(&[
        "tissue",
        "compress",
        &scenario,
        "--out-dir",
        s(&out),
        "--json",
    ]);
    ok(&o);
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).expect("JSON");
    let stages = v["report"]["stages"].as_array().unwrap();
    assert_eq!(stages.len(), 2);
    assert_eq!(v["report"]["markers"], 286);
    assert!(stages[1]["midplane_max_abs_uy_mm"].as_f64().unwrap() < 1e-9);
    let csv = std::fs::read_to_string(out.join("markers.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 2 * 286);
    for f in ["markers_top.svg", "markers_section.svg", "summary.json"] {
        assert!(out.join(f).exists(), "{f}");
    }
    let o = softjoint(&["tissue", "compress", "--print-default"]);
    ok(&o);
    assert!(stdout(&o).contains("gaps_mm"));
}

#[test]
fn bad_compression_scenarios_are_refused_by_name() {
    let dir = scratch("tissue-compress-bad");
    let typo = file(&dir, "typo.toml", "gap_mm = [90.0]\n");
    refused(
        &["tissue", "compress", &typo],
        &["typo.toml", "unknown field `gap_mm`"],
    );
    let wide = file(&dir, "wide.toml", "gaps_mm = [120.0]\nmesh_divisions = 2\n");
    refused(
        &["tissue", "compress", &wide],
        &["wide.toml", "gaps_mm", "below the body's width"],
    );
    let nu = file(&dir, "nu.toml", "poisson_ratio = 0.5\nmesh_divisions = 2\n");
    refused(&["tissue", "compress", &nu], &["poisson_ratio"]);
    let neg = file(&dir, "neg.toml", "step_mm = -1.0\nmesh_divisions = 2\n");
    refused(&["tissue", "compress", &neg], &["step_mm"]);
    refused(
        &["tissue", "compress", "/nonexistent/x.toml"],
        &["/nonexistent/x.toml"],
    );
}
