//! `softjoint tissue`: inner deformation of soft tissue (seed 000).
//!
//! * `field` — Zhang's deformation-field measurement on two NIfTI volumes,
//!   or on a synthetic twin with a known warp (`--synthetic`), where the
//!   errors against the true field are reported too;
//! * `compress` — Kita's phantom compressed between two plates by the FEM
//!   and by the geometric model (A1/A2), with marker tables and pictures.
//!
//! The physics lives in `plant_tissue`; this is argument handling,
//! files, pictures and reports. Every command writes CSV and SVG into
//! `--out-dir` and prints a text summary or, with `--json`, a JSON one.
use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand, ValueEnum};
use host_tools::outln;
use host_tools::output::{self, JsonObject};
use host_tools::plot::{Anchor, Stroke, Svg};
use plant_tissue::compress::compare::{
    run as run_compression, CompressionOutcome, CompressionReport, CompressionSpec,
};
use plant_tissue::compress::phantom::MARKER_SPACING_MM;
use plant_tissue::field::experiment::{
    self, FieldOutcome, VariantField, VariantSummary, VolumePair,
};
use plant_tissue::field::matching::Consistency;
use plant_tissue::field::pipeline::{FieldParams, MeasuredField};
use plant_tissue::field::synth::{make_twin, SynthSpec, Twin};
use plant_tissue::field::twin::TwinReport;
use plant_tissue::field::volume::Volume;

/// Arguments of `softjoint tissue`.
#[derive(Args)]
pub struct TissueArgs {
    #[command(subcommand)]
    command: TissueCommand,
}

#[derive(Subcommand)]
enum TissueCommand {
    /// Measure the deformation field between two volumes (Zhang): Harris
    /// points, matching, Horn, Delaunay tetrahedra, shape functions, Eq. 12.
    Field(FieldArgs),
    /// Compress the semi-ellipsoidal phantom between two plates (Kita): FEM
    /// and geometric model, markers at each plate gap.
    Compress(CompressArgs),
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum MatchingArg {
    /// Strength of matches with the direction constraint (J = diff + A).
    Direction,
    /// Strength of matches alone.
    Strength,
    /// Eq. 5 as printed.
    AsPrinted,
    /// All three, on the same feature points.
    All,
}

impl MatchingArg {
    fn variants(self) -> Vec<Consistency> {
        match self {
            MatchingArg::Direction => vec![Consistency::Direction],
            MatchingArg::Strength => vec![Consistency::StrengthOnly],
            MatchingArg::AsPrinted => vec![Consistency::DirectionAsPrinted],
            // The paper's method first: the pictures and field.csv show it.
            MatchingArg::All => vec![
                Consistency::Direction,
                Consistency::StrengthOnly,
                Consistency::DirectionAsPrinted,
            ],
        }
    }
}

#[derive(Args)]
struct FieldArgs {
    /// Initial volume (NIfTI: .nii, .nii.gz, .hdr/.img).
    initial: Option<PathBuf>,
    /// Deformed volume, on the same grid.
    deformed: Option<PathBuf>,
    /// Make a synthetic twin with a known warp instead of reading volumes.
    #[arg(long)]
    synthetic: bool,
    /// Size of the synthetic twin, `NXxNYxNZ` (the paper's: 256x256x57).
    #[arg(long, default_value = "256x256x57", value_parser = parse_dims)]
    dims: [usize; 3],
    /// Seed of the synthetic twin and the Delaunay jitter.
    #[arg(allow_negative_numbers = true, long, default_value_t = 1)]
    seed: u64,
    /// Feature points in the initial volume (Table I: 1000).
    #[arg(allow_negative_numbers = true, long, default_value_t = 1000)]
    features_initial: usize,
    /// Feature points in the deformed volume (Table I: 5000).
    #[arg(allow_negative_numbers = true, long, default_value_t = 5000)]
    features_deformed: usize,
    /// Matching variant.
    #[arg(long, value_enum, default_value = "direction")]
    matching: MatchingArg,
    /// Write the synthetic pair as `initial.nii.gz` and `deformed.nii.gz`.
    #[arg(long)]
    write_volumes: bool,
    /// Dense field rows every this many voxels in x and y (all slices).
    #[arg(allow_negative_numbers = true, long, default_value_t = 8)]
    grid_step: usize,
    /// Output directory (created).
    #[arg(long)]
    out_dir: PathBuf,
    /// Print a JSON summary instead of text.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
struct CompressArgs {
    /// Scenario (TOML, the fields of `--print-default`); without it the
    /// paper's phantom compressed to 100 and 80 mm.
    scenario: Option<PathBuf>,
    /// Print the default scenario as TOML and exit.
    #[arg(long)]
    print_default: bool,
    /// Output directory (created).
    #[arg(long)]
    out_dir: Option<PathBuf>,
    /// Print a JSON summary instead of text.
    #[arg(long)]
    json: bool,
}

fn parse_dims(s: &str) -> std::result::Result<[usize; 3], String> {
    let parts: Vec<&str> = s.split(['x', 'X']).collect();
    if parts.len() != 3 {
        return Err(format!("`{s}`: expected NXxNYxNZ, e.g. 128x128x32"));
    }
    let mut d = [0usize; 3];
    for (slot, p) in d.iter_mut().zip(&parts) {
        *slot = p
            .trim()
            .parse()
            .map_err(|_| format!("`{s}`: `{p}` is not a whole number of voxels"))?;
        if !(16..=1024).contains(slot) {
            return Err(format!("`{s}`: each side must be 16 to 1024 voxels"));
        }
    }
    Ok(d)
}

/// Runs a `softjoint tissue` subcommand.
pub fn run(args: TissueArgs) -> Result<()> {
    match args.command {
        TissueCommand::Field(a) => field(&a),
        TissueCommand::Compress(a) => compress(&a),
    }
}

fn out_dir(dir: &Path) -> Result<()> {
    fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))
}

/// Writes a CSV or SVG through `host_tools::output`, which refuses
/// non-finite numbers.
fn write(path: &Path, text: &str) -> Result<()> {
    if path.extension().is_some_and(|e| e == "csv") {
        output::write_csv(path, text)
    } else {
        output::write_svg(path, text)
    }
}

/// A number for a CSV: finite values only (a non-finite one is a bug here
/// and is refused rather than written).
fn num(v: f64) -> Result<String> {
    if v.is_finite() {
        Ok(format!("{v:.6}"))
    } else {
        bail!("internal error: a non-finite value reached a result file")
    }
}

/// Peak memory of `field --synthetic` per voxel of the twin (bytes) and
/// besides it: measured as the maximum resident set of `softjoint tissue
/// field --synthetic --dims 128x128x32` (77 MB) and `128x128x64` (137 MB),
/// `/usr/bin/time -v`, ≈ 115 B a voxel over ≈ 17 MB; rounded up.
const FIELD_BYTES_PER_VOXEL: u64 = 120;
const FIELD_BYTES_BESIDES: u64 = 32_000_000;

fn field(a: &FieldArgs) -> Result<()> {
    if a.grid_step == 0 {
        bail!("--grid-step must be at least 1");
    }
    if a.synthetic {
        // Refused before the twin is allocated (1024³ aborted in the
        // allocator with SIGABRT).
        let voxels: u64 = a.dims.iter().map(|&d| d as u64).product();
        let [nx, ny, nz] = a.dims;
        host_tools::memory::check_fits(
            &format!("--dims {nx}x{ny}x{nz} ({voxels} voxels)"),
            voxels * FIELD_BYTES_PER_VOXEL + FIELD_BYTES_BESIDES,
        )?;
    }
    let pair = load_pair(a)?;
    if a.write_volumes && pair.twin().is_none() {
        bail!("--write-volumes writes the synthetic pair: use it with --synthetic");
    }
    out_dir(&a.out_dir)?;
    let mut written: Vec<String> = Vec::new();
    if a.write_volumes {
        for (name, v) in [
            ("initial.nii.gz", pair.initial()),
            ("deformed.nii.gz", pair.deformed()),
        ] {
            v.write_nifti(&a.out_dir.join(name))?;
            written.push(name.into());
        }
    }
    let params = FieldParams {
        features_initial: a.features_initial,
        features_deformed: a.features_deformed,
        seed: a.seed,
        ..FieldParams::default()
    };
    if params.features_initial < 4 || params.features_deformed < 4 {
        bail!("--features-initial and --features-deformed must be at least 4");
    }
    let outcome = experiment::run(&pair, &params, &a.matching.variants())?;
    written.extend(write_field_files(&a.out_dir, &pair, &outcome, a.grid_step)?);
    written.push("summary.json".into());
    let summary = field_summary(pair.initial(), &outcome)?.field("files", &written)?;
    output::write_json(&a.out_dir.join("summary.json"), &summary)?;
    if a.json {
        output::print_json(&summary)?;
        return Ok(());
    }
    print_field_table(pair.initial(), &outcome)?;
    outln!("wrote {} to {}", written.join(", "), a.out_dir.display());
    Ok(())
}

/// The two volumes: read from INITIAL and DEFORMED, or a synthetic twin.
fn load_pair(a: &FieldArgs) -> Result<VolumePair> {
    match (&a.initial, &a.deformed, a.synthetic) {
        (Some(i), Some(d), false) => Ok(VolumePair::Files {
            initial: Volume::read_nifti(i)?,
            deformed: Volume::read_nifti(d)?,
        }),
        (None, None, true) => {
            let t = make_twin(&SynthSpec {
                seed: a.seed,
                ..SynthSpec::with_dims(a.dims)
            })?;
            Ok(VolumePair::Twin(Box::new(t)))
        }
        (_, _, true) => {
            bail!("--synthetic makes its own volumes: give no INITIAL/DEFORMED files with it")
        }
        _ => bail!(
            "give two volumes (INITIAL DEFORMED), or --synthetic for a twin with a known warp"
        ),
    }
}

/// matches.csv (every variant), field.csv (the first variant's dense
/// field, every `grid_step` voxels) and, with more than one variant,
/// field_<variant>.csv for each of the others, and mid_slice.svg (the
/// first variant's); returns the names written, in order.
fn write_field_files(
    dir: &Path,
    pair: &VolumePair,
    outcome: &FieldOutcome,
    grid_step: usize,
) -> Result<Vec<String>> {
    let first = &outcome.variants[0];
    let mut names = vec!["matches.csv".to_string(), "field.csv".to_string()];
    write(
        &dir.join("matches.csv"),
        &matches_csv(outcome, pair.twin())?,
    )?;
    write(
        &dir.join("field.csv"),
        &dense_csv(pair.initial(), first, grid_step)?,
    )?;
    for v in &outcome.variants[1..] {
        let name = format!("field_{}.csv", v.consistency.name());
        write(&dir.join(&name), &dense_csv(pair.initial(), v, grid_step)?)?;
        names.push(name);
    }
    let svg = mid_slice_picture(
        pair.initial(),
        &first.measured,
        first.consistency,
        pair.twin(),
        grid_step,
    );
    write(&dir.join("mid_slice.svg"), &svg)?;
    names.push("mid_slice.svg".into());
    Ok(names)
}

/// Every variant's matches with their displacement (and, on a twin, the
/// true displacement and the error).
fn matches_csv(outcome: &FieldOutcome, twin: Option<&Twin>) -> Result<String> {
    let mut csv = String::from("matching,x_mm,y_mm,z_mm,dx_mm,dy_mm,dz_mm,correlation,strength");
    if twin.is_some() {
        csv.push_str(",true_dx_mm,true_dy_mm,true_dz_mm,error_mm");
    }
    csv.push('\n');
    for v in &outcome.variants {
        let m = &v.measured;
        for (k, mm) in m.matches.iter().enumerate() {
            let p = m.field.nodes_mm[k];
            let d = m.field.displacement_mm[k];
            let mut row = vec![v.consistency.name().to_string()];
            for x in p.iter().chain(&d).chain(&[mm.correlation, mm.strength]) {
                row.push(num(*x)?);
            }
            if let Some(t) = twin {
                let td = t.warp.displacement_mm(p);
                let e = ((0..3).map(|i| (d[i] - td[i]).powi(2)).sum::<f64>()).sqrt();
                for x in td.iter().chain(&[e]) {
                    row.push(num(*x)?);
                }
            }
            let _ = writeln!(csv, "{}", row.join(","));
        }
    }
    Ok(csv)
}

/// The dense field of the first variant, every `grid_step` voxels in x
/// and y on every slice, where its tetrahedra cover the voxel.
fn dense_csv(iv: &Volume, first: &VariantField, grid_step: usize) -> Result<String> {
    let dims = iv.dims();
    let dense = first.measured.field.dense(dims, iv.spacing_mm());
    let mut dcsv = format!("# dense field of `{}` matching, every {} voxels in x and y\nx_mm,y_mm,z_mm,dx_mm,dy_mm,dz_mm\n", first.consistency.name(), grid_step);
    for z in 0..dims[2] {
        for y in (0..dims[1]).step_by(grid_step) {
            for x in (0..dims[0]).step_by(grid_step) {
                if let Some(u) = dense.displacement_mm[iv.index(x, y, z)] {
                    let p = iv.position_mm([x, y, z]);
                    let vals = [
                        p[0],
                        p[1],
                        p[2],
                        f64::from(u[0]),
                        f64::from(u[1]),
                        f64::from(u[2]),
                    ];
                    let row: Vec<String> = vals.iter().map(|v| num(*v)).collect::<Result<_>>()?;
                    let _ = writeln!(dcsv, "{}", row.join(","));
                }
            }
        }
    }
    Ok(dcsv)
}

fn field_summary(iv: &Volume, outcome: &FieldOutcome) -> Result<JsonObject> {
    let per_variant: Vec<&VariantSummary> = outcome.variants.iter().map(|v| &v.summary).collect();
    JsonObject::new()
        .field("dims", &iv.dims())?
        .field("spacing_mm", &iv.spacing_mm())?
        .field("features_initial", &outcome.features.initial.len())?
        .field("features_deformed", &outcome.features.deformed.len())?
        .field("measure_seconds", &outcome.measure_seconds)?
        .field("variants", &per_variant)?
        .field("against_truth", &outcome.against_truth)
}

fn print_field_table(iv: &Volume, outcome: &FieldOutcome) -> Result<()> {
    let (dims, sp) = (iv.dims(), iv.spacing_mm());
    outln!(
        "{}×{}×{} voxels of {:.3}×{:.3}×{:.3} mm; {} + {} feature points; measured in {:.2} s",
        dims[0],
        dims[1],
        dims[2],
        sp[0],
        sp[1],
        sp[2],
        outcome.features.initial.len(),
        outcome.features.deformed.len(),
        outcome.measure_seconds
    );
    outln!(
        "{:<11} {:>8} {:>11} {:>10} {:>11}",
        "matching",
        "matches",
        "tetrahedra",
        "Horn (°)",
        "Eq. 12 RMS"
    );
    for v in &outcome.variants {
        let s = &v.summary;
        outln!(
            "{:<11} {:>8} {:>11} {:>10.3} {:>11.3}",
            s.matching,
            s.matches,
            s.tetrahedra,
            s.horn_angle_deg,
            s.registration_rms.unwrap_or(f64::NAN)
        );
    }
    if let Some(r) = &outcome.against_truth {
        print_truth_table(r)?;
    }
    Ok(())
}

fn print_truth_table(r: &TwinReport) -> Result<()> {
    outln!(
        "against the known field (common voxels; Eq. 12 unregistered {:.2}, true field {:.2}):",
        r.rms_unregistered,
        r.rms_true_field
    );
    outln!(
        "{:<11} {:>6} {:>14} {:>14} {:>11} {:>13}",
        "matching",
        "wrong",
        "match RMS (mm)",
        "dense RMS (mm)",
        "Eq. 12 RMS",
        "Horn err (°)"
    );
    for v in &r.variants {
        outln!(
            "{:<11} {:>6} {:>14.3} {:>14.3} {:>11.3} {:>13.4}",
            v.consistency.name(),
            v.wrong_matches,
            v.match_endpoint_rms_mm,
            v.dense_endpoint_rms_mm,
            v.registration_rms,
            v.rotation_error_deg
        );
    }
    Ok(())
}

/// The initial volume's middle slice in grey with the measured field as
/// arrows (and the true field, for a twin), arrows drawn 3× long.
fn mid_slice_picture(
    iv: &Volume,
    m: &MeasuredField,
    c: Consistency,
    twin: Option<&Twin>,
    step: usize,
) -> String {
    let [nx, ny, nz] = iv.dims();
    let sp = iv.spacing_mm();
    let z = nz / 2;
    let block = nx.max(ny).div_ceil(64).max(1);
    let px = 640.0 / (nx as f64 * sp[0]).max(ny as f64 * sp[1]);
    let (w, h) = (nx as f64 * sp[0] * px, ny as f64 * sp[1] * px);
    let mut svg = Svg::new(w + 20.0, h + 70.0);
    let (lo, hi) = iv
        .data()
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(l, h), v| {
            (l.min(*v), h.max(*v))
        });
    let span = f64::from(hi - lo).max(1e-9);
    let (ox, oy) = (10.0, 40.0);
    for by in (0..ny).step_by(block) {
        for bx in (0..nx).step_by(block) {
            let mut acc = 0.0;
            let mut cnt = 0.0;
            for y in by..(by + block).min(ny) {
                for x in bx..(bx + block).min(nx) {
                    acc += f64::from(iv.at(x, y, z));
                    cnt += 1.0;
                }
            }
            let g = (255.0 * ((acc / cnt - f64::from(lo)) / span)).clamp(0.0, 255.0) as u8;
            svg.rect(
                ox + bx as f64 * sp[0] * px,
                oy + by as f64 * sp[1] * px,
                block as f64 * sp[0] * px + 0.5,
                block as f64 * sp[1] * px + 0.5,
                &format!("rgb({g},{g},{g})"),
                None,
            );
        }
    }
    let dense = m.field.dense(iv.dims(), sp);
    let to_px = |p: [f64; 3]| (ox + p[0] * px, oy + p[1] * px);
    for y in (0..ny).step_by(step) {
        for x in (0..nx).step_by(step) {
            let p = iv.position_mm([x, y, z]);
            if let Some(t) = twin {
                let q = t.warp.forward_mm(p);
                let e = [p[0] + 3.0 * (q[0] - p[0]), p[1] + 3.0 * (q[1] - p[1]), p[2]];
                if dense.displacement_mm[iv.index(x, y, z)].is_some() {
                    svg.arrow(to_px(p), to_px(e), 4.0, Stroke::solid("#2a2", 1.6));
                }
            }
            if let Some(u) = dense.displacement_mm[iv.index(x, y, z)] {
                let e = [
                    p[0] + 3.0 * f64::from(u[0]),
                    p[1] + 3.0 * f64::from(u[1]),
                    p[2],
                ];
                svg.arrow(to_px(p), to_px(e), 4.0, Stroke::solid("#e22", 1.1));
            }
        }
    }
    let title = format!(
        "slice {z} of {nz}: measured field ({} matching, red){}",
        c.name(),
        if twin.is_some() {
            ", true field (green)"
        } else {
            ""
        }
    );
    svg.text_styled(
        ox,
        18.0,
        14.0,
        Anchor::Start,
        r#"font-weight="bold""#,
        &title,
    );
    svg.text(
        ox,
        34.0,
        12.0,
        Anchor::Start,
        &format!(
            "{} matches, {} tetrahedra; arrows 3× long; x to the right, y down; {:.3} mm voxels",
            m.matches.len(),
            m.field.tets.len(),
            sp[0]
        ),
    );
    svg.text(
        ox,
        oy + h + 20.0,
        12.0,
        Anchor::Start,
        "grey: initial volume; arrows only where the matches' tetrahedra cover the slice",
    );
    svg.finish()
}

fn load_spec(path: &Path) -> Result<CompressionSpec> {
    let text = fs::read_to_string(path)
        .with_context(|| format!("cannot read scenario {}", path.display()))?;
    toml::from_str(&text)
        .map_err(|e| anyhow::anyhow!("{}: {}", path.display(), e.to_string().trim_end()))
}

fn compress(a: &CompressArgs) -> Result<()> {
    if a.print_default {
        host_tools::output::print_toml("", &CompressionSpec::default())?;
        return Ok(());
    }
    let spec = match &a.scenario {
        Some(p) => load_spec(p)?,
        None => CompressionSpec::default(),
    };
    let label = a.scenario.as_ref().map_or_else(
        || "the default phantom".to_string(),
        |p| p.display().to_string(),
    );
    let t0 = Instant::now();
    let out = run_compression(&spec).with_context(|| format!("compressing {label}"))?;
    let seconds = t0.elapsed().as_secs_f64();
    if let Some(dir) = &a.out_dir {
        out_dir(dir)?;
        write(&dir.join("markers.csv"), &markers_csv(&out)?)?;
        write(
            &dir.join("markers_top.svg"),
            &markers_picture(&out, View::Top),
        )?;
        write(
            &dir.join("markers_section.svg"),
            &markers_picture(&out, View::Section),
        )?;
    }
    let summary = JsonObject::new()
        .field("seconds", &seconds)?
        .field("report", &out.report)?;
    if let Some(dir) = &a.out_dir {
        output::write_json(&dir.join("summary.json"), &summary)?;
    }
    if a.json {
        output::print_json(&summary)?;
        return Ok(());
    }
    print_compress_table(&out.report, seconds)?;
    if let Some(dir) = &a.out_dir {
        outln!(
            "wrote markers.csv, markers_top.svg, markers_section.svg, summary.json to {}",
            dir.display()
        );
    }
    Ok(())
}

fn print_compress_table(r: &CompressionReport, seconds: f64) -> Result<()> {
    outln!(
        "{} markers, {} nodes, {} tetrahedra; FEM and geometric model in {:.2} s",
        r.markers,
        r.nodes,
        r.tetrahedra,
        seconds
    );
    outln!(
        "{:>7} {:>9} {:>14} {:>16} {:>16} {:>12} {:>18}",
        "gap mm",
        "force N",
        "mid-plane |uy|",
        "pressed uy/ux",
        "outer ux/uy",
        "J pressed",
        "geometric err mm"
    );
    for s in &r.stages {
        outln!(
            "{:>7.1} {:>9.2} {:>14.2e} {:>7.2}/{:<8.2} {:>7.2}/{:<8.2} {:>12.4} {:>8.2} (max {:.2})",
            s.gap_mm,
            s.plate_force_n,
            s.midplane_max_abs_uy_mm,
            s.pressed_mean_abs_uy_mm,
            s.pressed_mean_abs_ux_mm,
            s.outer_mean_abs_ux_mm,
            s.outer_mean_abs_uy_mm,
            s.volume_ratio_pressed,
            s.geometric_error_mean_mm,
            s.geometric_error_max_mm
        );
    }
    Ok(())
}

fn markers_csv(o: &CompressionOutcome) -> Result<String> {
    let mut s = String::from(
        "gap_mm,marker,x0_mm,y0_mm,z0_mm,pressed,fem_x_mm,fem_y_mm,fem_z_mm,geometric_x_mm,geometric_y_mm,geometric_z_mm,error_mm\n",
    );
    for st in &o.stages {
        for (k, m) in o.markers_mm.iter().enumerate() {
            let f = st.fem_mm[k];
            let g = st.geometric_mm[k];
            let e = ((0..3).map(|i| (f[i] - g[i]).powi(2)).sum::<f64>()).sqrt();
            let vals: Vec<String> = m.iter().map(|v| num(*v)).collect::<Result<_>>()?;
            let fv: Vec<String> = f
                .iter()
                .chain(&g)
                .chain(&[e])
                .map(|v| num(*v))
                .collect::<Result<_>>()?;
            let _ = writeln!(
                s,
                "{},{k},{},{},{}",
                num(st.gap_mm)?,
                vals.join(","),
                u8::from(st.pressed[k]),
                fv.join(",")
            );
        }
    }
    Ok(s)
}

#[derive(Clone, Copy, PartialEq)]
enum View {
    /// The x–y plane of the marker layer at z ≈ 21 mm (the paper's Fig. 8b).
    Top,
    /// The y–z cross-section for compression nearest x = 0.
    Section,
}

/// Markers of one plane: initial (grey), FEM (filled, one colour per gap)
/// and geometric model (hollow), with the plates.
fn markers_picture(o: &CompressionOutcome, view: View) -> String {
    let [a, b, c] = o.body.semi_axes_mm;
    // The plane: the second marker layer (Top) or the cross-section nearest x = 0.
    let layer_z = {
        let mut zs: Vec<f64> = o.markers_mm.iter().map(|m| m[2]).collect();
        zs.sort_by(f64::total_cmp);
        zs.dedup();
        zs.get(1).copied().unwrap_or(zs[0])
    };
    let section_x = o
        .markers_mm
        .iter()
        .map(|m| m[0])
        .filter(|x| *x > 0.0)
        .fold(f64::INFINITY, f64::min);
    let chosen: Vec<usize> = (0..o.markers_mm.len())
        .filter(|&k| match view {
            View::Top => o.markers_mm[k][2] == layer_z,
            View::Section => o.markers_mm[k][0] == section_x,
        })
        .collect();
    // Horizontal and vertical axes (mm) of the picture.
    let (hx, vy) = match view {
        View::Top => (0, 1),
        View::Section => (1, 2),
    };
    let (h_lo, h_hi, v_lo, v_hi) = match view {
        View::Top => (-a - 15.0, a + 15.0, -b - 10.0, b + 10.0),
        View::Section => (-b - 10.0, b + 10.0, -5.0, c + 25.0),
    };
    let scale = 760.0 / (h_hi - h_lo);
    let (ox, oy) = (20.0, 60.0);
    let w = (h_hi - h_lo) * scale;
    let hgt = (v_hi - v_lo) * scale;
    let to = |p: [f64; 3]| (ox + (p[hx] - h_lo) * scale, oy + (v_hi - p[vy]) * scale);
    let mut svg = Svg::new(w + 40.0, hgt + 110.0);
    let colours = ["#d62", "#26c", "#2a2", "#a2a"];
    // The body's outline in that plane.
    let outline: Vec<(f64, f64)> = (0..=180)
        .map(|i| {
            let t = std::f64::consts::PI * i as f64 / 90.0;
            match view {
                View::Top => {
                    let r = (1.0 - (layer_z / c).powi(2)).max(0.0).sqrt();
                    to([a * r * t.cos(), b * r * t.sin(), layer_z])
                }
                View::Section => {
                    let r = (1.0 - (section_x / a).powi(2)).max(0.0).sqrt();
                    let th = std::f64::consts::PI * i as f64 / 180.0;
                    to([section_x, b * r * th.cos(), c * r * th.sin()])
                }
            }
        })
        .collect();
    svg.polyline(outline, Stroke::dashed("#888", 1.0));
    for (si, st) in o.stages.iter().enumerate() {
        let col = colours[si % colours.len()];
        let hgap = 0.5 * st.gap_mm;
        for sign in [-1.0, 1.0] {
            let (p1, p2) = match view {
                View::Top => (
                    to([h_lo, sign * hgap, layer_z]),
                    to([h_hi, sign * hgap, layer_z]),
                ),
                View::Section => (
                    to([section_x, sign * hgap, v_lo]),
                    to([section_x, sign * hgap, v_hi]),
                ),
            };
            svg.line(p1, p2, Stroke::dashed(col, 1.2));
        }
        for &k in &chosen {
            let from = to(o.markers_mm[k]);
            svg.line(from, to(st.fem_mm[k]), Stroke::solid(col, 0.8));
            svg.dot(to(st.fem_mm[k]), 3.0, col);
            svg.circle(to(st.geometric_mm[k]), 4.5, Stroke::solid(col, 1.0));
        }
    }
    for &k in &chosen {
        svg.dot(to(o.markers_mm[k]), 2.5, "#555");
    }
    let title = match view {
        View::Top => format!("markers of the layer z = {layer_z} mm (x to the right, y up; cf. Kita Fig. 8b)"),
        View::Section => format!("markers of the cross-section x = {section_x} mm (y to the right, z up from the chest wall)"),
    };
    svg.text_styled(
        ox,
        20.0,
        14.0,
        Anchor::Start,
        r#"font-weight="bold""#,
        &title,
    );
    let mut legend = String::from("grey: uncompressed; filled dots: FEM; rings: geometric model (A1/A2); dashed lines: plates at ");
    for (si, st) in o.stages.iter().enumerate() {
        let _ = write!(
            legend,
            "{}{} mm ({})",
            if si > 0 { ", " } else { "" },
            st.gap_mm,
            ["orange", "blue", "green", "purple"][si % 4]
        );
    }
    svg.text(ox, 40.0, 12.0, Anchor::Start, &legend);
    let note = format!(
        "lattice spacing {MARKER_SPACING_MM} mm; markers drawn where the plane holds them; distances to scale ({scale:.1} px/mm)"
    );
    svg.text(ox, oy + hgt + 30.0, 12.0, Anchor::Start, &note);
    svg.finish()
}
