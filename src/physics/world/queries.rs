//! Queries of the current state: energies, momenta, contact and fracture counts, fragments,
//! probes (interpolation at a reference point) and the nearest particle.
use super::World;
use crate::physics::dim::{Dim, Mat, Space, Vect};
use crate::physics::fracture;
use crate::physics::params::ElasticModel;

impl<const D: usize> World<D>
where
    Space: Dim<D>,
{
    /// Kinetic energy of translation and rotation (J).
    pub fn kinetic_energy(&self) -> f64 {
        // (A follower's motion is its constraint's: it carries no kinetic energy of its own.)
        let following = &self.op.second.following;
        (0..self.len())
            .filter(|&i| !following.get(i).copied().unwrap_or(false))
            .map(|i| {
                0.5 * self.p.mass[i] * self.p.v[i].norm_squared()
                    + 0.5 * self.p.inertia[i] * <Space as Dim<D>>::ang_dot(self.p.w[i], self.p.w[i])
            })
            .sum()
    }

    /// Elastic strain energy of the current state (J).
    pub fn strain_energy(&self) -> f64 {
        self.op.strain_energy(&self.p, &self.bonds, &self.scratch)
    }

    /// Contact potential energy of the current state (J): the work the contact forces have
    /// stored; kinetic + strain + contact energy is conserved between bond breaks (a break
    /// releases the strain energy of the bond).
    pub fn contact_energy(&self) -> f64 {
        if self.contact.active {
            self.contact.energy(&self.p.x0, &self.p.u, &self.p.body)
        } else {
            0.0
        }
    }

    /// Pairs in contact now (closer than l0 and repelling), each pair once.
    pub fn contact_pairs(&self) -> usize {
        if self.contact.active {
            self.contact.pairs_in_contact(&self.p.x0, &self.p.u)
        } else {
            0
        }
    }

    /// Contact pair-list builds (cell-grid searches) so far; stays 0 when no search is needed
    /// (one body and fracture off, or contact disabled).
    pub fn contact_searches(&self) -> u64 {
        self.contact.searches
    }

    /// Force evaluations so far in which a pair of one body was within its contact distance
    /// (`Contact::same_body_touches`): while 0, `contact.fractured_surfaces` has changed nothing.
    pub fn same_body_touches(&self) -> u64 {
        self.contact.same_body_touches
    }

    /// Surface flag of particle i, Eq. (41) (or lost a bond, Eq. (42)).
    pub fn is_surface(&self, i: usize) -> bool {
        self.contact.surface[i]
    }

    /// Broken bonds of particle i.
    pub fn broken_bonds_of(&self, i: usize) -> u32 {
        fracture::broken_of(&self.bonds, i)
    }

    /// Number of separate fragments: connected components over the intact bonds (computed on
    /// demand, O(bonds)). Bodies that never broke count one each.
    pub fn fragments(&self) -> usize {
        fracture::fragments(&self.bonds, self.len())
    }

    /// Largest strain over the intact bonds now (-), and a particle that has it (O(bonds)).
    pub fn max_bond_strain(&self) -> (f64, usize) {
        fracture::max_bond_strain(&self.p.u, &self.bonds)
    }

    /// Sizes of the fragments as (body, particles), in order of their lowest particle index.
    pub fn fragment_sizes(&self) -> Vec<(u32, usize)> {
        let root = fracture::components(&self.bonds, self.len());
        let mut count = vec![0usize; self.len()];
        for &r in &root {
            count[r as usize] += 1;
        }
        (0..self.len())
            .filter(|&i| root[i] == i as u32)
            .map(|i| (self.p.body[i], count[i]))
            .collect()
    }

    /// Pairs closer than l0 now: (different bodies, one body across a broken bond).
    pub fn contact_pairs_by_kind(&self) -> (usize, usize) {
        if self.contact.active {
            self.contact
                .pairs_by_kind(&self.p.x0, &self.p.u, &self.p.body)
        } else {
            (0, 0)
        }
    }

    /// Total linear momentum (kg m/s).
    pub fn momentum(&self) -> Vect<D> {
        (0..self.len()).fold(Vect::<D>::zeros(), |acc, i| {
            acc + self.p.v[i] * self.p.mass[i]
        })
    }

    /// Total angular momentum about the origin, orbital plus spin (kg m^2/s).
    pub fn angular_momentum(&self) -> <Space as Dim<D>>::Ang {
        (0..self.len()).fold(<Space as Dim<D>>::ang_zero(), |acc, i| {
            let orb = <Space as Dim<D>>::cross(&self.p.x[i], &(self.p.v[i] * self.p.mass[i]));
            let spin = <Space as Dim<D>>::ang_scale(self.p.w[i], self.p.inertia[i]);
            <Space as Dim<D>>::ang_add(acc, <Space as Dim<D>>::ang_add(orb, spin))
        })
    }

    /// Internal force on particle i at the current state (N).
    pub fn internal_force(&self, i: usize) -> Vect<D> {
        self.force[i]
    }

    /// Displacement at a reference point near particle i: u_i + H_i (X - X_i), with the
    /// displacement gradient H_i from the corrected gradient operator (exact for linear fields).
    pub fn displacement_at(&self, i: usize, point: &Vect<D>) -> Vect<D> {
        self.interpolate_at(i, point, |j| self.p.displacement(j))
    }

    /// Velocity at a reference point near particle i (m/s), interpolated like
    /// [`World::displacement_at`].
    pub fn velocity_at(&self, i: usize, point: &Vect<D>) -> Vect<D> {
        self.interpolate_at(i, point, |j| self.p.v[j])
    }

    /// A particle field f at a reference point near particle i: f_i plus the operator's gradient
    /// of f at i times the offset from i's reference position (and, for the second-order
    /// operator, half its Hessian times the offset squared: exact for quadratic fields).
    fn interpolate_at(&self, i: usize, point: &Vect<D>, f: impl Fn(usize) -> Vect<D>) -> Vect<D> {
        let fi = f(i);
        let d = point - self.p.x0[i];
        let mut g = Mat::<D>::zeros();
        if self.op.model == ElasticModel::SecondOrder {
            let so = &self.op.second;
            // A ghost carries its master's field reflected (as in the fits).
            let fj = |j: usize| match so.ghost_of(j) {
                Some(g) => g.reflect(&f(j), &f(g.master as usize)),
                None => f(j),
            };
            let mut q = Vect::<D>::zeros();
            for b in self.bonds.of(i) {
                if so.weight(&self.bonds, b) == 0.0 {
                    continue;
                }
                let df = fj(self.bonds.nbr[b] as usize) - fi;
                g += df * so.grad_weight(&self.bonds, i, b).transpose();
                q += df * d.dot(&(so.hess_weight(&self.bonds, i, b) * d));
            }
            return fi + g * d + q * 0.5;
        }
        for b in self.bonds.of(i) {
            let r0 = self.bonds.r0[b];
            let om = self.bonds.w0[b] / r0.norm_squared();
            let df = f(self.bonds.nbr[b] as usize) - fi;
            g += (df * om) * r0.transpose();
        }
        fi + g * self.op.k_inv[i] * d
    }

    /// Mean displacement (m) and mean velocity (m/s) of the particles of load region r: the
    /// motion work-conjugate to the region's force (spread evenly over the same particles).
    pub fn load_motion(&self, r: usize) -> (Vect<D>, Vect<D>) {
        let m = &self.loads[r].members;
        let n = m.len().max(1) as f64;
        let (mut u, mut v) = (Vect::<D>::zeros(), Vect::<D>::zeros());
        for &i in m {
            u += self.p.displacement(i as usize);
            v += self.p.v[i as usize];
        }
        (u / n, v / n)
    }

    /// Index of the particle of `body` (any body when None) nearest to a reference point, and
    /// its distance. Ties (a point half way between particles, as a probe on a beam's axis) go
    /// to the lowest index among the particles within 1e-6 l0 of the nearest distance, so the
    /// choice does not depend on round-off, i.e. on where the scene sits.
    pub fn nearest_particle(&self, point: &Vect<D>, body: Option<u32>) -> Option<(usize, f64)> {
        let dist = |i: usize| (self.p.x0[i] - point).norm();
        let mine = |i: &usize| body.is_none_or(|b| self.p.body[*i] == b);
        let dmin = (0..self.len())
            .filter(mine)
            .map(dist)
            .min_by(|a, b| a.total_cmp(b))?;
        (0..self.len())
            .filter(mine)
            .map(|i| (i, dist(i)))
            .find(|&(_, d)| d <= dmin + 1e-6 * self.l0)
    }
}
