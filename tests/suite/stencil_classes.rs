//! The second-order operator's weights interned by set (issue 25, physics::stencils): a
//! lattice body has few distinct sets, each particle's set is bit for bit the fit computed for
//! it alone (the set-up computes a fit once per distinct neighbourhood), and a particle that
//! lost bonds gets a set of its own while the others keep theirs.
use mps_solid::physics::ElasticModel;
use mps_solid::scene::Model;
use mps_solid::studies::peers::cube_scene;
use mps_solid::Scene;

/// The benchmark cube with a step on top (a second box over half its top face): a body the
/// boundary closure does not serve, so each particle keeps its lattice fit. (A body the closure
/// serves gets per-particle corrections, shared only along the layers its reduced box repeats,
/// i.e. in bodies more than 17 particles across.)
fn on_a_step(scene: &mut Scene) {
    let side = scene.bodies[0].boxes[0].max[0];
    scene.bodies[0].boxes.push(mps_solid::scene::Region {
        min: vec![0.0, 0.0, side],
        max: vec![side / 2.0, side, side + 3.0 * scene.particle_spacing],
    });
}

#[test]
fn a_lattice_cube_has_few_weight_sets_and_each_is_the_particles_own_fit() {
    let mut scene = cube_scene(10, 0.025, ElasticModel::SecondOrder, 1e-5);
    on_a_step(&mut scene);
    let m = Model::<3>::build(&scene).unwrap();
    let w = &m.world;
    let so = &w.op.second;
    let n = w.len();
    let classes = so.stencils.classes();
    // Along each axis a particle is one of 0, 1, 2+ layers from either face (5 kinds), and the
    // clamped layer and its neighbours differ: some hundreds of sets, not one per particle.
    assert!(classes * 4 < n, "{classes} sets for {n} particles");
    // Every particle's set is its own fit: refit each from scratch (no sharing) and compare.
    let mut fresh = so.clone();
    for i in 0..n {
        fresh.refresh(&w.bonds, w.l0, i);
        let (a, b) = (so.stencils.of(i), fresh.stencils.of(i));
        assert_eq!(a.len(), b.len(), "particle {i}");
        assert!(
            a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()),
            "particle {i}: its shared set differs from its own fit"
        );
        assert_eq!(so.quadratic[i], fresh.quadratic[i]);
        assert_eq!(so.full[i], fresh.full[i]);
        assert_eq!(so.span[i], fresh.span[i]);
    }
    // Refitting adds no set: they were all there.
    assert_eq!(fresh.stencils.classes(), classes);
}

#[test]
fn a_particle_that_loses_bonds_gets_its_own_set_and_gets_its_built_set_back() {
    let mut scene = cube_scene(8, 0.025, ElasticModel::SecondOrder, 1e-5);
    on_a_step(&mut scene);
    let mut m = Model::<3>::build(&scene).unwrap();
    let w = &mut m.world;
    // An interior particle shares its set with others.
    let i = (0..w.len())
        .find(|&i| {
            w.op.second
                .stencils
                .class
                .iter()
                .filter(|&&c| c == w.op.second.stencils.class[i])
                .count()
                > 4
        })
        .unwrap();
    let before = w.op.second.stencils.class[i];
    let state = w.state();
    let b = w.bonds.of(i).start;
    let j = w.bonds.nbr[b] as usize;
    let back = mps_solid::physics::second_order::mirror_index(&w.bonds)[b] as usize;
    w.bonds.w0[b] = 0.0;
    w.bonds.w0[back] = 0.0;
    w.op.refresh_particle(&w.bonds, i, w.p.n_ref[i]);
    w.op.refresh_particle(&w.bonds, j, w.p.n_ref[j]);
    let after = w.op.second.stencils.class[i];
    assert_ne!(after, before);
    assert_eq!(
        w.op.second
            .stencils
            .class
            .iter()
            .filter(|&&c| c == after)
            .count(),
        1,
        "the cut particle's set is its own"
    );
    // The state from before the break brings the bond and the built set back.
    w.set_state(&state).unwrap();
    assert_eq!(w.op.second.stencils.class[i], before);
}
