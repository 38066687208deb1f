//! The contacts of a state one by one, with their forces: what a script reads to see inside a
//! step (`mochi.Simulation.contact_data`). The cpu backend evaluates them for every backend
//! (`engines::cpu::contact_data`), by the Rust law that each backend's law is checked against.

/// The id of box wall `w` (`2·axis + side`, the low wall of x first) as a contact's partner:
/// −1 … −6.
pub fn box_wall_id(w: u32) -> i64 {
    -1 - w as i64
}

/// The id of the scene's mesh wall `k` (its `[[wall]]` table from 0) as a contact's partner:
/// −7, −8, …
pub fn mesh_wall_id(k: usize) -> i64 {
    -7 - k as i64
}

/// The contacts of a state, as the next step resolves them: each touching pair of spheres once
/// (the lower input index first) and each contact of a sphere with a wall, the forces on the
/// first partner (the second takes the opposite), and the sums each sphere's step adds up.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ContactData {
    /// The partners of each contact: `[i, j]` with spheres i < j (input indices), or `[i, w]`
    /// with a wall's negative id w ([`box_wall_id`], [`mesh_wall_id`]); a sphere touching a
    /// mesh wall at several triangles has a contact for each.
    pub pairs: Vec<[i64; 2]>,
    /// The normal force on the first partner \[N\].
    pub normal_force: Vec<[f32; 3]>,
    /// The tangential (friction) force on the first partner \[N\].
    pub tangential_force: Vec<[f32; 3]>,
    /// How far the partners overlap \[m\].
    pub overlap: Vec<f32>,
    /// Each sphere's contact force as its step sums it (pairs, then walls) \[N\].
    pub forces: Vec<[f32; 3]>,
    /// Each sphere's contact torque about its centre \[N·m\] (zeros where the step does not
    /// turn its spheres).
    pub torques: Vec<[f32; 3]>,
}

impl ContactData {
    /// Number of contacts.
    pub fn len(&self) -> usize {
        self.pairs.len()
    }

    /// Whether nothing touches.
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// Appends a contact.
    pub(crate) fn push(
        &mut self,
        pair: [i64; 2],
        normal: [f32; 3],
        tangential: [f32; 3],
        overlap: f32,
    ) {
        self.pairs.push(pair);
        self.normal_force.push(normal);
        self.tangential_force.push(tangential);
        self.overlap.push(overlap);
    }
}
