//! Shared builders for the integration tests.
#![allow(dead_code)]
use mps_solid::physics::boundary::GravityLaw;
use mps_solid::physics::world::GroupInit;
use mps_solid::physics::{
    BodyInit, Dim, ElasticModel, Material, MaterialLaw, SolverOptions, Space, Vect, World,
};

pub const STEEL_LIKE: Material = Material {
    density: 1000.0,
    young: 1.0e7,
    poisson: 0.3,
    law: MaterialLaw::SaintVenantKirchhoff,
};

/// A block of nx x ny (x nz) particles at spacing l0, centred on the origin.
pub fn block<const D: usize>(n: [usize; 3], l0: f64) -> Vec<Vect<D>> {
    let mut pts = Vec::new();
    let total: usize = n[..D].iter().product();
    for code in 0..total {
        let mut c = code;
        let mut p = Vect::<D>::zeros();
        for a in 0..D {
            p[a] = ((c % n[a]) as f64 - 0.5 * (n[a] - 1) as f64) * l0;
            c /= n[a];
        }
        pts.push(p);
    }
    pts
}

/// A free body (no gravity, no supports) of the given model.
pub fn free_world<const D: usize>(n: [usize; 3], model: ElasticModel) -> World<D>
where
    Space: Dim<D>,
{
    let l0 = 0.01;
    let opts = SolverOptions {
        model,
        ..SolverOptions::default()
    };
    let body = BodyInit {
        name: "block".into(),
        material: STEEL_LIKE,
        points: block::<D>(n, l0),
        velocity: Vect::<D>::zeros().into(),
        shape: None,
    };
    World::new(
        l0,
        opts,
        vec![body],
        Vec::<GroupInit>::new(),
        vec![],
        GravityLaw::Constant(Vect::<D>::zeros()),
    )
    .unwrap()
}

/// Deterministic pseudo-random numbers in [-0.5, 0.5).
pub struct Rng(pub u64);
impl Rng {
    pub fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    }
}

pub const MODELS: [ElasticModel; 4] = [
    ElasticModel::SecondOrder,
    ElasticModel::Corrected,
    ElasticModel::Paper,
    ElasticModel::PaperLocal,
];

/// The cdylib cargo built with this test: the newer of target/<profile>/deps/libmps_solid.so and
/// target/<profile>/libmps_solid.so (cargo builds the library's cdylib for the package's
/// integration tests but uplifts it to target/<profile>/ only in `cargo build`, so the copy
/// there may be stale).
pub fn built_library() -> std::path::PathBuf {
    let exe = std::env::current_exe().unwrap();
    let deps = exe.parent().unwrap();
    let profile = if deps.ends_with("deps") {
        deps.parent().unwrap()
    } else {
        deps
    };
    let mtime = |p: &std::path::PathBuf| std::fs::metadata(p).and_then(|m| m.modified()).ok();
    [
        profile.join("deps/libmps_solid.so"),
        profile.join("libmps_solid.so"),
    ]
    .into_iter()
    .filter(|p| p.exists())
    .max_by_key(mtime)
    .unwrap_or_else(|| panic!("libmps_solid.so not found next to {}", exe.display()))
}

/// Checks that the internal forces at `state` are minus the gradient of the strain energy along
/// `v`: f . v = -dE/du . v by central differences with eps = 1e-6 l0, to 1e-6 relative. The
/// difference quotient's truncation is ~1e-10 relative and the round-off of E ~1e-11, so 1e-6
/// is far below any error of a force term (a missing term is O(1)). Leaves `w` at a perturbed
/// state.
pub fn assert_forces_are_minus_the_energy_gradient_along(
    w: &mut World<3>,
    state: &mps_solid::physics::world::WorldState<3>,
    v: &[Vect<3>],
    what: &str,
) {
    w.set_state(state).unwrap();
    let fv: f64 = (0..w.len()).map(|i| w.internal_force(i).dot(&v[i])).sum();
    let eps = 1e-6 * w.l0;
    let mut e = [0.0; 2];
    for (k, s) in [1.0, -1.0].iter().enumerate() {
        let mut st = state.clone();
        for (ui, vi) in st.u.iter_mut().zip(v) {
            *ui += vi * (s * eps);
        }
        w.set_state(&st).unwrap();
        e[k] = w.strain_energy();
    }
    let de = (e[0] - e[1]) / (2.0 * eps);
    assert!(fv.abs() > 0.0 && e[0].is_finite(), "{what}: f.v = {fv:e}");
    assert!(
        (fv + de).abs() <= 1e-6 * fv.abs(),
        "{what}: f.v = {fv:e}, -dE/du.v = {:e}",
        -de
    );
}
