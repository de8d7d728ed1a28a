//! Kita's breast-compression phantom on the twin (seed 000, L2363–2522):
//! the facts of the paper's Fig. 8 from the FEM model, A2 on the
//! mid-plane, and the geometric model's marker error against the FEM at
//! 100 and 80 mm. A coarse mesh and 2.5 mm plate steps keep it quick in a
//! debug build; the README has the figures of the default mesh.
use plant_tissue::compress::compare::{run, CompressionOutcome, CompressionSpec};
use plant_tissue::compress::phantom::PHANTOM_MARKERS;
use std::sync::OnceLock;

fn coarse() -> &'static CompressionOutcome {
    static O: OnceLock<CompressionOutcome> = OnceLock::new();
    O.get_or_init(|| {
        run(&CompressionSpec {
            mesh_divisions: 4,
            step_mm: 2.5,
            ..CompressionSpec::default()
        })
        .expect("phantom compresses")
    })
}

#[test]
fn the_phantom_twin_has_the_papers_size_and_markers() {
    let o = coarse();
    assert_eq!(o.report.markers, PHANTOM_MARKERS);
    assert_eq!(o.body.semi_axes_mm, [65.0, 55.0, 70.0]);
    let gaps: Vec<f64> = o.report.stages.iter().map(|s| s.gap_mm).collect();
    assert_eq!(gaps, vec![100.0, 80.0]);
    // Every marker ends between the plates.
    for st in &o.stages {
        for m in &st.fem_mm {
            assert!(
                m[1].abs() <= 0.5 * st.gap_mm + 1e-9,
                "{m:?} at {} mm",
                st.gap_mm
            );
        }
    }
}

#[test]
fn a2_the_mid_plane_stays_undeformed_in_y_but_not_in_x() {
    for s in &coarse().report.stages {
        assert!(
            s.midplane_max_abs_uy_mm < 1e-9,
            "{} mm: |u_y| {}",
            s.gap_mm,
            s.midplane_max_abs_uy_mm
        );
    }
    // Kita's amendment 2: the mid-plane's displacement along x is not
    // negligible at 80 mm.
    let s80 = &coarse().report.stages[1];
    assert!(
        s80.midplane_mean_abs_ux_mm > 1.0,
        "{}",
        s80.midplane_mean_abs_ux_mm
    );
}

#[test]
fn markers_under_the_plates_move_mostly_in_y_and_outer_ones_in_x() {
    for s in &coarse().report.stages {
        assert!(s.markers_pressed > 0 && s.markers_outer > 0);
        assert!(
            s.pressed_mean_abs_uy_mm > 2.0 * s.pressed_mean_abs_ux_mm,
            "{} mm pressed: |u_y| {} vs |u_x| {}",
            s.gap_mm,
            s.pressed_mean_abs_uy_mm,
            s.pressed_mean_abs_ux_mm
        );
        assert!(s.pressed_y_dominant > 0.5, "{}", s.pressed_y_dominant);
    }
    let s80 = &coarse().report.stages[1];
    assert!(
        s80.outer_mean_abs_ux_mm > 1.5 * s80.outer_mean_abs_uy_mm,
        "outer: |u_x| {} vs |u_y| {}",
        s80.outer_mean_abs_ux_mm,
        s80.outer_mean_abs_uy_mm
    );
    assert!(s80.outer_x_dominant > 0.7, "{}", s80.outer_x_dominant);
}

#[test]
fn the_pressed_part_gets_denser_than_the_rest() {
    for s in &coarse().report.stages {
        assert!(
            s.volume_ratio_pressed < 1.0,
            "J = {}",
            s.volume_ratio_pressed
        );
        assert!(s.volume_ratio_pressed < s.volume_ratio_outer);
    }
}

#[test]
fn the_geometric_models_marker_error_against_the_fem_grows_with_compression() {
    let s = &coarse().report.stages;
    eprintln!(
        "geometric vs FEM: {} mm mean {:.2} max {:.2}; {} mm mean {:.2} max {:.2}",
        s[0].gap_mm,
        s[0].geometric_error_mean_mm,
        s[0].geometric_error_max_mm,
        s[1].gap_mm,
        s[1].geometric_error_mean_mm,
        s[1].geometric_error_max_mm
    );
    assert!(s[0].geometric_error_mean_mm > 0.0 && s[0].geometric_error_mean_mm < 2.0);
    assert!(s[1].geometric_error_mean_mm > 2.0 * s[0].geometric_error_mean_mm);
    assert!(s[1].geometric_error_max_mm < 15.0);
    // The plates push harder the further they go.
    assert!(s[0].plate_force_n > 0.0 && s[1].plate_force_n > 3.0 * s[0].plate_force_n);
}

#[test]
fn bad_schedules_are_refused_by_name() {
    let e = run(&CompressionSpec {
        gaps_mm: vec![80.0, 100.0],
        ..CompressionSpec::default()
    })
    .unwrap_err();
    assert!(e.to_string().contains("gaps_mm"), "{e}");
    let e = run(&CompressionSpec {
        gaps_mm: vec![120.0],
        ..CompressionSpec::default()
    })
    .unwrap_err();
    assert!(e.to_string().contains("below the body's width"), "{e}");
    let e = run(&CompressionSpec {
        poisson_ratio: 0.5,
        ..CompressionSpec::default()
    })
    .unwrap_err();
    assert!(e.to_string().contains("poisson_ratio"), "{e}");
}
