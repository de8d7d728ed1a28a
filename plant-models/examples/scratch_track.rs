use plant_models::contour::fit::Solver;
use plant_models::contour::identify::distance::point_polygon_distance;
use plant_models::contour::identify::gcv::Lambda;
use plant_models::contour::identify::tracked::{fit_closed_curve, ContourOptions};
use plant_models::pushing::reference::{record_push, ReferenceConfig, ReferenceMaterial};
use plant_models::pushing::scenario::{PushScenario, PushSite};
fn main() {
    let mat = ReferenceMaterial::SPONGE;
    let sc = PushScenario::seed(PushSite::MiddleLongSide, mat.scale_px_per_m).unwrap();
    let el: f64 = std::env::args()
        .nth(1)
        .map(|s| s.parse().unwrap())
        .unwrap_or(16.0);
    let noisy = record_push(
        "s",
        mat,
        &sc,
        &ReferenceConfig {
            element_size_px: el,
            ..Default::default()
        },
    )
    .unwrap();
    let clean = record_push(
        "s",
        mat,
        &sc,
        &ReferenceConfig {
            element_size_px: el,
            contour_noise_px: 0.0,
            ..Default::default()
        },
    )
    .unwrap();
    let n = noisy.contours_px[0].len();
    println!("points per contour {n}");
    for frac in [0.25, 0.5, 1.0] {
        for lam in [Lambda::Gcv, Lambda::Fixed(1e-4), Lambda::Fixed(1e-2)] {
            let knots = ((n as f64) * frac) as usize;
            let t = std::time::Instant::now();
            let mut raw = 0.0;
            let mut sp = 0.0;
            let mut spmax: f64 = 0.0;
            let mut lams = vec![];
            for f in [0usize, 25, 50, 75, 99] {
                let pts: Vec<(f64, f64)> =
                    noisy.contours_px[f].iter().map(|p| (p.x, p.y)).collect();
                let truth: Vec<(f64, f64)> =
                    clean.contours_px[f].iter().map(|p| (p.x, p.y)).collect();
                let fit = fit_closed_curve(
                    "f",
                    &pts,
                    &ContourOptions {
                        knots,
                        lambda: lam,
                        solver: Solver::Reduced,
                    },
                )
                .unwrap();
                lams.push(fit.lambda.lambda);
                raw += pts
                    .iter()
                    .map(|&p| point_polygon_distance(p, &truth))
                    .sum::<f64>()
                    / pts.len() as f64;
                let s = fit.curve.sample(1200);
                let d: Vec<f64> = s
                    .iter()
                    .map(|&p| point_polygon_distance(p, &truth))
                    .collect();
                sp += d.iter().sum::<f64>() / d.len() as f64;
                spmax = spmax.max(d.iter().cloned().fold(0.0, f64::max));
            }
            println!(
                "knots {knots} λ {lam:?}: raw {:.3} spline {:.3} max {:.2} λ {:?} ({:.1} ms/frame)",
                raw / 5.0,
                sp / 5.0,
                spmax,
                lams.iter().map(|l| format!("{l:.1e}")).collect::<Vec<_>>(),
                t.elapsed().as_secs_f64() * 1000.0 / 5.0
            );
        }
    }
}
