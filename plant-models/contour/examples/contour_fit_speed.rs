//! Per-frame time of the signature fit with knots and λ given, without
//! the command line's file reading and writing (issue 34): reads a
//! `frame,angle_rad,radius` CSV once, then times, REPS times each, (a) the
//! fit alone (`fit_signature`: one banded penalised least-squares solve
//! per frame) and (b) everything `softjoint contour fit --model signature`
//! computes per frame (`fit_contours`: the fit, the two half-data fits,
//! the data polygon, the gap and self-intersection sampling, the report's
//! samples). Prints the median per frame of each in ms, and the first
//! frame's spline coefficients' rms radius residual for a sanity check.
//!
//! `cargo run --release -p plant-contour --example contour_fit_speed -- FILE KNOTS LAMBDA [REPS] [SAMPLES]`
//! (`scripts/contour_speed_fitpack.py` runs it beside FITPACK). Exit 2 for
//! a bad argument or file.
use plant_contour::fit::Solver;
use plant_contour::identify::contours::{fit_contours, ContourFitSpec, ContourModel};
use plant_contour::identify::data::{read_contour_csv, FrameData};
use plant_contour::identify::gcv::Lambda;
use plant_contour::identify::tracked::{fit_signature, ContourOptions};
use std::process::ExitCode;
use std::time::Instant;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: contour_fit_speed FILE KNOTS LAMBDA [REPS] [SAMPLES]";
    let (Some(file), Some(Ok(knots)), Some(Ok(lambda))) = (
        args.first(),
        args.get(1).map(|s| s.parse::<usize>()),
        args.get(2).map(|s| s.parse::<f64>()),
    ) else {
        eprintln!("{usage}");
        return ExitCode::from(2);
    };
    let reps = args.get(3).map_or(Ok(5), |s| s.parse::<usize>());
    let samples = args.get(4).map_or(Ok(64), |s| s.parse::<usize>());
    let (Ok(reps), Ok(samples)) = (reps, samples) else {
        eprintln!("{usage}");
        return ExitCode::from(2);
    };
    let text = match std::fs::read_to_string(file) {
        Ok(t) => t,
        Err(e) => {
            eprintln!("reading {file}: {e}");
            return ExitCode::from(2);
        }
    };
    let data = match read_contour_csv(&text, file) {
        Ok(d) => d,
        Err(e) => {
            eprintln!("{e}");
            return ExitCode::from(2);
        }
    };
    let sigs: Vec<_> = data
        .frames
        .iter()
        .filter_map(|(_, f)| match f {
            FrameData::Signature(s) => Some(s.clone()),
            FrameData::Points(_) => None,
        })
        .collect();
    if sigs.len() != data.frames.len() || sigs.is_empty() {
        eprintln!("{file}: needs frame,angle_rad,radius signature data");
        return ExitCode::from(2);
    }
    let opts = ContourOptions {
        knots,
        lambda: Lambda::Fixed(lambda),
        solver: Solver::Reduced,
    };
    let spec = ContourFitSpec {
        model: Some(ContourModel::Signature),
        knots: Some(knots),
        time_knots: None,
        lambda: Lambda::Fixed(lambda),
        solver: Solver::Reduced,
        samples,
        signed_radii: false,
    };
    let frames = sigs.len() as f64;
    let (mut fit_only, mut whole) = (Vec::new(), Vec::new());
    let mut rms = 0.0;
    for _ in 0..reps {
        let t0 = Instant::now();
        for (k, s) in sigs.iter().enumerate() {
            match fit_signature("frame", s, &opts) {
                Ok(f) if k == 0 => rms = f.rms_residual,
                Ok(_) => {}
                Err(e) => {
                    eprintln!("{e}");
                    return ExitCode::from(2);
                }
            }
        }
        fit_only.push(t0.elapsed().as_secs_f64() / frames);
        let t0 = Instant::now();
        if let Err(e) = fit_contours(&data, &spec) {
            eprintln!("{e}");
            return ExitCode::from(2);
        }
        whole.push(t0.elapsed().as_secs_f64() / frames);
    }
    println!("fit_only_ms {:.5}", 1e3 * median(fit_only));
    println!("fit_and_checks_ms {:.5}", 1e3 * median(whole));
    println!("first_frame_rms {rms:.6}");
    ExitCode::SUCCESS
}
