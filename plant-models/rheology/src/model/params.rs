//! The lattice's material parameters in the paper's units, the element
//! classes they apply to, and the paper's search ranges and defaults.
//!
//! Units. The seed prints K in "gf/cm³" and C1, C2 in "gfs/cm³"
//! (L1838). An element constant per volume does not make a spring, so we
//! read K as a modulus in gf/cm² and C1, C2 as viscosities in gf·s/cm²: a
//! voxel of edge h contributes springs of `K·h/a` and dampers of
//! `C1·h/a`, `C2·h/(1−a)` (a spring of modulus K, cross-section h² and
//! length a·h; see [`super::element`]). On the paper's sparse 1 cm lattice
//! (L1925) that is K/a gf/cm numerically, and the same parameters describe
//! the same material at any lattice spacing. K is the modulus of one
//! element's spring, not of the block: K = 500 gf/cm² is 49 kPa, but the
//! lattice of such elements has a Young's modulus of (144/19)·K/a ≈ 7.6·K/a
//! and a Poisson ratio of 5/19 ([`super::effective`]), so the paper's
//! defaults (a = 0.5) are a block of E ≈ 743 kPa (15.2·K), a stiff dough.
use serde::{Deserialize, Serialize};

use crate::error::{bad_setting, check_positive, check_range, Result, RheologyError};

/// One gram-force in newtons (exact by definition).
pub const GF_N: f64 = 9.806_65e-3;
/// 1 gf/cm² in pascals.
pub const PA_PER_GF_PER_CM2: f64 = GF_N / 1e-4;

/// The four constants of the paper's basic element (L1739–1742), for one
/// class of elements.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ElementParams {
    /// Elastic coefficient K of the Voigt spring (gf/cm²).
    pub k_gf_per_cm2: f64,
    /// Viscous coefficient C1 of the Voigt damper (gf·s/cm²).
    pub c1_gfs_per_cm2: f64,
    /// Viscous coefficient C2 of the series damper (gf·s/cm²).
    pub c2_gfs_per_cm2: f64,
    /// Length ratio a of the Voigt part to the whole element (0 < a < 1).
    pub a: f64,
}

impl ElementParams {
    /// The paper's defaults (L1838, L1946): K = 500, C1 = C2 = 2000, a = 0.5.
    pub const PAPER_DEFAULT: Self = Self {
        k_gf_per_cm2: 500.0,
        c1_gfs_per_cm2: 2000.0,
        c2_gfs_per_cm2: 2000.0,
        a: 0.5,
    };

    /// Checks every constant; names the field (prefixed by `what`).
    pub fn validate(&self, what: &str) -> Result<()> {
        check_positive(&format!("{what}.k_gf_per_cm2"), self.k_gf_per_cm2)?;
        check_positive(&format!("{what}.c1_gfs_per_cm2"), self.c1_gfs_per_cm2)?;
        check_positive(&format!("{what}.c2_gfs_per_cm2"), self.c2_gfs_per_cm2)?;
        if !(self.a.is_finite() && self.a > 0.0 && self.a < 1.0) {
            return Err(RheologyError::InvalidParameter {
                name: format!("{what}.a"),
                value: self.a,
                reason: "the length ratio must be in (0, 1)",
            });
        }
        Ok(())
    }

    fn to_genes(self) -> [f64; 4] {
        [
            self.k_gf_per_cm2,
            self.c1_gfs_per_cm2,
            self.c2_gfs_per_cm2,
            self.a,
        ]
    }

    fn from_genes(g: &[f64]) -> Self {
        Self {
            k_gf_per_cm2: g[0],
            c1_gfs_per_cm2: g[1],
            c2_gfs_per_cm2: g[2],
            a: g[3],
        }
    }
}

/// Which elements a parameter class covers. A voxel is a *surface* voxel
/// when one of its faces lies on the block's boundary, else a *core*
/// voxel (L1891–1895). Its elements are *on* the voxel (the 12 edges and
/// 12 face diagonals) or *in* it (the 4 body diagonals, or with the local
/// volume condition the 8 half-diagonals to its centre mass; L1979–1991).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ElementClass {
    SurfaceOn = 0,
    SurfaceIn = 1,
    CoreOn = 2,
    CoreIn = 3,
}

impl ElementClass {
    /// All four classes, in index order.
    pub const ALL: [ElementClass; 4] = [
        ElementClass::SurfaceOn,
        ElementClass::SurfaceIn,
        ElementClass::CoreOn,
        ElementClass::CoreIn,
    ];

    /// The class of an element of a voxel.
    pub fn of(surface_voxel: bool, inside_voxel: bool) -> Self {
        match (surface_voxel, inside_voxel) {
            (true, false) => ElementClass::SurfaceOn,
            (true, true) => ElementClass::SurfaceIn,
            (false, false) => ElementClass::CoreOn,
            (false, true) => ElementClass::CoreIn,
        }
    }

    /// Snake-case name, as in scenario files.
    pub fn name(self) -> &'static str {
        match self {
            ElementClass::SurfaceOn => "surface_on",
            ElementClass::SurfaceIn => "surface_in",
            ElementClass::CoreOn => "core_on",
            ElementClass::CoreIn => "core_in",
        }
    }
}

/// Material parameters of a whole lattice: one [`ElementParams`] per class.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LatticeParams {
    pub surface_on: ElementParams,
    pub surface_in: ElementParams,
    pub core_on: ElementParams,
    pub core_in: ElementParams,
}

impl LatticeParams {
    /// Every class with the same constants.
    pub fn uniform(p: ElementParams) -> Self {
        Self {
            surface_on: p,
            surface_in: p,
            core_on: p,
            core_in: p,
        }
    }

    /// The paper's defaults in every class (L1838).
    pub fn paper_default() -> Self {
        Self::uniform(ElementParams::PAPER_DEFAULT)
    }

    /// The constants of one class.
    pub fn get(&self, c: ElementClass) -> &ElementParams {
        match c {
            ElementClass::SurfaceOn => &self.surface_on,
            ElementClass::SurfaceIn => &self.surface_in,
            ElementClass::CoreOn => &self.core_on,
            ElementClass::CoreIn => &self.core_in,
        }
    }

    fn get_mut(&mut self, c: ElementClass) -> &mut ElementParams {
        match c {
            ElementClass::SurfaceOn => &mut self.surface_on,
            ElementClass::SurfaceIn => &mut self.surface_in,
            ElementClass::CoreOn => &mut self.core_on,
            ElementClass::CoreIn => &mut self.core_in,
        }
    }

    /// Checks every class; the error names `class.field`.
    pub fn validate(&self) -> Result<()> {
        for c in ElementClass::ALL {
            self.get(c).validate(c.name())?;
        }
        Ok(())
    }
}

/// How many parameters a calibration searches, and how they map to the
/// element classes (L1885–1915, L1957–1991).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ParamSet {
    /// K, C1, C2, a shared by every element (the paper's Model 1, 4 parameters).
    Four,
    /// Surface and core voxels apart (8 parameters, L1891–1915).
    Eight,
    /// Surface/core × in/on (16 parameters, the paper's Models 2′ and 4′,
    /// L1957–1991).
    Sixteen,
}

/// The search interval of one parameter.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ParamRange {
    /// Name, `class.field` (for messages, CSV columns and JSON).
    pub name: String,
    pub min: f64,
    pub max: f64,
}

/// The paper's "stable parameter intervals" for 4 and 8 parameters
/// (L1808–1811): K 100–3000, C1 500–100000, C2 500–200000, a 0.3–0.7.
/// (The tables' GA results end at K = 3000, C2 = 20000, which hints that
/// narrower intervals were used in practice; we take them as printed.)
pub const PAPER_RANGES: [(f64, f64); 4] = [
    (100.0, 3000.0),
    (500.0, 100_000.0),
    (500.0, 200_000.0),
    (0.3, 0.7),
];

/// The 16-parameter intervals of elements in a voxel (L1957–1975).
pub const PAPER_RANGES_IN: [(f64, f64); 4] = [
    (50.0, 3000.0),
    (250.0, 10_000.0),
    (250.0, 20_000.0),
    (0.3, 0.7),
];

/// The 16-parameter intervals of elements on a voxel (L1957–1975).
pub const PAPER_RANGES_ON: [(f64, f64); 4] = [
    (100.0, 3000.0),
    (500.0, 10_000.0),
    (500.0, 20_000.0),
    (0.3, 0.7),
];

const FIELDS: [&str; 4] = ["k_gf_per_cm2", "c1_gfs_per_cm2", "c2_gfs_per_cm2", "a"];

impl ParamSet {
    /// Number of parameters.
    pub fn len(self) -> usize {
        match self {
            ParamSet::Four => 4,
            ParamSet::Eight => 8,
            ParamSet::Sixteen => 16,
        }
    }

    /// Never empty (for clippy's `len_without_is_empty`).
    pub fn is_empty(self) -> bool {
        false
    }

    /// From a count (4, 8 or 16).
    pub fn from_count(n: usize) -> Result<Self> {
        match n {
            4 => Ok(ParamSet::Four),
            8 => Ok(ParamSet::Eight),
            16 => Ok(ParamSet::Sixteen),
            _ => Err(bad_setting(
                "params",
                format!("the paper calibrates 4, 8 or 16 parameters, not {n}"),
            )),
        }
    }

    /// The groups of classes that share one parameter block, in gene order.
    fn groups(self) -> Vec<(String, Vec<ElementClass>)> {
        use ElementClass::*;
        match self {
            ParamSet::Four => vec![("all".into(), ElementClass::ALL.to_vec())],
            ParamSet::Eight => vec![
                ("surface".into(), vec![SurfaceOn, SurfaceIn]),
                ("core".into(), vec![CoreOn, CoreIn]),
            ],
            ParamSet::Sixteen => ElementClass::ALL
                .iter()
                .map(|&c| (c.name().to_string(), vec![c]))
                .collect(),
        }
    }

    /// The search ranges in gene order (the paper's).
    pub fn ranges(self) -> Vec<ParamRange> {
        let mut out = Vec::with_capacity(self.len());
        for (group, classes) in self.groups() {
            let table = match self {
                ParamSet::Sixteen => {
                    if matches!(classes[0], ElementClass::SurfaceIn | ElementClass::CoreIn) {
                        PAPER_RANGES_IN
                    } else {
                        PAPER_RANGES_ON
                    }
                }
                _ => PAPER_RANGES,
            };
            for (f, (min, max)) in FIELDS.iter().zip(table) {
                out.push(ParamRange {
                    name: format!("{group}.{f}"),
                    min,
                    max,
                });
            }
        }
        out
    }

    /// Lattice parameters from a gene vector (in [`Self::ranges`] order).
    pub fn to_lattice(self, genes: &[f64]) -> Result<LatticeParams> {
        if genes.len() != self.len() {
            return Err(bad_setting(
                "params",
                format!("expected {} values, got {}", self.len(), genes.len()),
            ));
        }
        let mut p = LatticeParams::paper_default();
        for (g, (_, classes)) in self.groups().into_iter().enumerate() {
            let e = ElementParams::from_genes(&genes[4 * g..4 * g + 4]);
            for c in classes {
                *p.get_mut(c) = e;
            }
        }
        p.validate()?;
        Ok(p)
    }

    /// The gene vector of lattice parameters (the first class of each group).
    pub fn genes_of(self, p: &LatticeParams) -> Vec<f64> {
        self.groups()
            .into_iter()
            .flat_map(|(_, classes)| p.get(classes[0]).to_genes())
            .collect()
    }

    /// Whether every gene lies in its range.
    pub fn check_in_ranges(self, genes: &[f64]) -> Result<()> {
        for (g, r) in genes.iter().zip(self.ranges()) {
            check_range(&r.name, *g, r.min, r.max)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gene_vectors_round_trip_through_lattice_parameters() {
        for set in [ParamSet::Four, ParamSet::Eight, ParamSet::Sixteen] {
            let ranges = set.ranges();
            assert_eq!(ranges.len(), set.len());
            let genes: Vec<f64> = ranges
                .iter()
                .enumerate()
                .map(|(i, r)| r.min + (r.max - r.min) * (i as f64 + 1.0) / 20.0)
                .collect();
            let p = set.to_lattice(&genes).unwrap();
            assert_eq!(set.genes_of(&p), genes);
        }
        let p = ParamSet::Eight
            .to_lattice(&[1000.0, 600.0, 700.0, 0.4, 200.0, 800.0, 900.0, 0.6])
            .unwrap();
        assert_eq!(p.surface_in.k_gf_per_cm2, 1000.0);
        assert_eq!(p.core_on.a, 0.6);
    }

    #[test]
    fn the_papers_ranges_and_bad_values_are_named() {
        let r = ParamSet::Sixteen.ranges();
        assert_eq!(r[0].name, "surface_on.k_gf_per_cm2");
        assert_eq!((r[0].min, r[0].max), (100.0, 3000.0));
        assert_eq!(r[4].name, "surface_in.k_gf_per_cm2");
        assert_eq!((r[4].min, r[4].max), (50.0, 3000.0));
        assert_eq!((r[6].min, r[6].max), (250.0, 20_000.0));
        let e = ParamSet::Four
            .to_lattice(&[500.0, 2000.0, 2000.0, 1.5])
            .unwrap_err();
        assert!(e.to_string().contains("surface_on.a"), "{e}");
        let e = ParamSet::Four
            .check_in_ranges(&[50.0, 2000.0, 2000.0, 0.5])
            .unwrap_err();
        assert!(e.to_string().contains("all.k_gf_per_cm2"), "{e}");
        assert!(ParamSet::from_count(5).is_err());
    }
}
