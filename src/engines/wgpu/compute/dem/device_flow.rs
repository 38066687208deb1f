//! Flow events on the device: the state scanned for spheres leaving, spheres appended into the
//! rows kept for them, leaving ones removed by moving the last rows over theirs. The same
//! removal and appending keep a rank's step on its device from round to round.

use super::*;
use crate::engines::common::flow::{
    Arriving, DeviceRows, Layer, LayerBounds, Named, Placed, ResidentStep,
};
use crate::engines::wgpu::halo::{HaloExchange, StateBuffers};
use crate::engines::wgpu::state::RowMover;

/// Flow events scan the state on the device and append inserted spheres to it, in rows kept
/// for them at opening ([`GridStepper::flowing_on`]).
impl DeviceFlow for GridStepper {
    fn scan(&mut self, query: &FlowQuery) -> Result<Option<Scan>> {
        // A clump leaves whole, where its centre is: the host's flows take it.
        if self
            .res
            .granular
            .as_ref()
            .is_some_and(|g| g.clumps().is_some())
        {
            return Ok(None);
        }
        let set = self.turn().set;
        let gpu = &self.res.gpu;
        let scan = self.flow_scan.get_or_insert_with(|| FlowScan::new(gpu));
        let pos = &self.res.sets[set].pos;
        let spin = self.res.granular.as_ref().map(|g| g.omega_of(set));
        scan.scan(gpu, pos, spin, self.n, query).map(Some)
    }

    fn append(&mut self, new: &[NewSphere]) -> Result<bool> {
        let k = new.len() as u32;
        if !self.room_for(new.iter().map(|s| s.radius), 0) {
            return Ok(false);
        }
        if k == 0 {
            return Ok(true);
        }
        let table = &self.params.materials;
        let pos: Vec<[f32; 4]> = new
            .iter()
            .map(|s| [s.centre[0], s.centre[1], s.centre[2], s.radius])
            .collect();
        let vel: Vec<[f32; 4]> = new
            .iter()
            .map(|s| {
                [
                    s.velocity[0],
                    s.velocity[1],
                    s.velocity[2],
                    table.mass(s.material as u32, s.radius),
                ]
            })
            .collect();
        let ids: Vec<u32> = (self.next_id..self.next_id + k).collect();
        self.next_id += k;
        self.name_ids_below(self.next_id);
        let (q, set) = (&self.res.gpu.queue, &self.res.sets[self.current]);
        let at = self.n as u64;
        q.write_buffer(&set.pos, at * 16, bytemuck::cast_slice(&pos));
        // Inserted at their f32 centres: no residual (the rows may hold a removed sphere's).
        let lo = vec![[0.0f32; 4]; new.len()];
        q.write_buffer(&set.lo, at * 16, bytemuck::cast_slice(&lo));
        q.write_buffer(&set.vel, at * 16, bytemuck::cast_slice(&vel));
        q.write_buffer(&set.ids, at * 4, bytemuck::cast_slice(&ids));
        let next = self.turn();
        if let Some(g) = &mut self.res.granular {
            let materials: Vec<u8> = new.iter().map(|s| s.material).collect();
            g.append(&self.res.gpu, next, &materials)?;
        }
        self.resize(self.n + k);
        Ok(true)
    }

    fn sum_wall_loads_within(&mut self, bounds: ([f32; 3], [f32; 3])) {
        if let Some(g) = &mut self.res.granular {
            g.mesh_mut().sum_loads_within(&self.res.gpu, bounds);
        }
    }

    fn resident(&mut self) -> Option<&mut dyn ResidentStep> {
        Some(self)
    }

    fn remove(&mut self, rows: &[u32]) -> Result<bool> {
        let k = rows.len() as u32;
        let Some(kept) = self.n.checked_sub(k) else {
            return Ok(false);
        };
        // The last rows that stay fill the places of those that leave before them.
        let mut leaving = rows.to_vec();
        leaving.sort_unstable();
        let holes = leaving.iter().copied().take_while(|&r| r < kept);
        let fillers = (kept..self.n).filter(|r| leaving.binary_search(r).is_err());
        let moves: Vec<(u32, u32)> = fillers.zip(holes).collect();
        if !moves.is_empty() {
            let next = self.turn();
            let gpu = &self.res.gpu;
            let mover = self.row_mover.get_or_insert_with(|| RowMover::new(gpu));
            let set = &self.res.sets[self.current];
            for rows in [&set.pos, &set.lo, &set.vel] {
                mover.run(gpu, &moves, 4, |r| (rows, r))?;
            }
            mover.run(gpu, &moves, 1, |r| (&set.ids, r))?;
            if let Some(g) = &self.res.granular {
                g.move_rows(gpu, mover, next, &moves)?;
            }
        }
        if let Some(g) = &mut self.res.granular {
            g.shrink(k);
        }
        self.resize(kept);
        Ok(true)
    }
}

/// A rank's step: the records of its spheres near the faces of the rank's box written and
/// those sent here placed on the device (`halo.wgsl`), spheres taken out and appended; the
/// history's partners read back where the rank counts its contacts.
impl ResidentStep for GridStepper {
    fn rows(&mut self) -> Result<DeviceRows> {
        let (gpu, n) = (&self.res.gpu, self.n as usize);
        let set = &self.res.sets[self.current];
        let omega = match &self.res.granular {
            Some(g) => gpu.read(g.omega_of(self.turn().set), n)?,
            None => vec![[0.0; 4]; n],
        };
        Ok(DeviceRows {
            pos: gpu.read(&set.pos, n)?,
            lo: gpu.read(&set.lo, n)?,
            vel: gpu.read(&set.vel, n)?,
            omega,
            ids: gpu.read(&set.ids, n)?,
        })
    }

    fn name(&mut self, names: &[Named]) -> Result<()> {
        self.with_halo(|step, halo, state| halo.name(&step.res.gpu, state, names))
    }

    fn forget(&mut self, wholes: &[u32]) -> Result<()> {
        self.with_halo(|step, halo, state| halo.forget(&step.res.gpu, state, wholes))
    }

    fn own_marks(&mut self) -> Result<Vec<u32>> {
        self.with_halo(|step, halo, _| halo.own_marks(&step.res.gpu))
    }

    fn sphere_contacts(&mut self) -> Result<Option<Vec<u32>>> {
        let Some(g) = self.res.granular.as_ref().filter(|g| g.keeps_history()) else {
            return Ok(None);
        };
        let gpu = &self.res.gpu;
        let ids: Vec<u32> = gpu.read(&self.res.sets[self.current].ids, self.n as usize)?;
        let order = InputOrder::of(&ids);
        g.contact_counts(gpu, self.turn(), Some(&order), false)
            .map(Some)
    }

    fn gather_layer(&mut self, bounds: &LayerBounds, layer: &mut Layer) -> Result<()> {
        self.with_halo(|step, halo, state| halo.gather(&step.res.gpu, state, bounds, layer))
    }

    fn place_layer(&mut self, bounds: &LayerBounds, received: &[Vec<u8>]) -> Result<Placed> {
        // Moved spheres are binned afresh, in a grid laid out over where they are now.
        (self.sort_next, self.counted, self.stale) = (true, false, true);
        self.with_halo(|step, halo, state| halo.place(&step.res.gpu, state, bounds, received))
    }

    fn fits(&self, leaving: usize, coming: &[Arriving]) -> bool {
        self.room_for(coming.iter().map(|a| a.sphere.radius), leaving as u32)
    }

    fn update(&mut self, leaving: &[u32], coming: &[Arriving]) -> Result<u32> {
        if !self.fits(leaving.len(), coming) {
            return Err(Error::Usage(
                "a rank's step has no room for its spheres".into(),
            ));
        }
        let new: Vec<NewSphere> = coming.iter().map(|a| a.sphere).collect();
        let first = self.next_id;
        if !(self.remove(leaving)? && self.append(&new)?) {
            return Err(Error::Usage(
                "a rank's step has no room for its spheres".into(),
            ));
        }
        // The appended rows' residuals and spins (appending gives them none).
        let at = (self.n as usize - coming.len()) as u64;
        let lo: Vec<[f32; 4]> = coming
            .iter()
            .map(|a| {
                let [x, y, z] = a.residual;
                [x, y, z, 0.0]
            })
            .collect();
        let (q, set) = (&self.res.gpu.queue, &self.res.sets[self.current]);
        q.write_buffer(&set.lo, at * 16, bytemuck::cast_slice(&lo));
        if let Some(g) = &self.res.granular {
            let omega: Vec<[f32; 4]> = coming
                .iter()
                .map(|a| {
                    let [x, y, z] = a.spin;
                    [x, y, z, a.sphere.material as f32]
                })
                .collect();
            q.write_buffer(
                g.omega_of(self.turn().set),
                at * 16,
                bytemuck::cast_slice(&omega),
            );
        }
        Ok(first)
    }
}

impl GridStepper {
    /// Grows the sorted places by stable id (where contacts apart come from the history) to
    /// hold every id below `end`, at least doubled, and binds the contact pass to them.
    fn name_ids_below(&mut self, end: u32) {
        let Some(lists) = self.res.near.as_mut().filter(|l| l.apart_from_history) else {
            return;
        };
        let held = lists.place_of_id.size() / 4;
        if u64::from(end) <= held {
            return;
        }
        let words = u64::from(end).max(2 * held);
        let none = wgpu::BufferUsages::empty();
        lists.place_of_id = (self.res.gpu).storage("mochi.dem.place_of_id", words * 4, none);
        self.rebind();
    }

    /// `work` with a rank's exchange (made at the first) and the state as it binds it.
    fn with_halo<R>(
        &mut self,
        work: impl FnOnce(&Self, &mut HaloExchange, &StateBuffers) -> Result<R>,
    ) -> Result<R> {
        let mut halo = (self.halo.take()).unwrap_or_else(|| HaloExchange::new(&self.res.gpu));
        let set = &self.res.sets[self.current];
        let state = StateBuffers {
            pos: &set.pos,
            lo: &set.lo,
            vel: &set.vel,
            omega: (self.res.granular.as_ref()).map(|g| g.omega_of(self.turn().set)),
            ids: &set.ids,
            n: self.n,
        };
        let done = work(self, &mut halo, &state);
        self.halo = Some(halo);
        done
    }

    /// Whether spheres of the radii `new` fit after those there less `leaving` of them: rows
    /// kept, the radii the grid's cells and levels were chosen for, stable ids below the walls'
    /// (a reopening numbers the spheres afresh).
    fn room_for(&self, new: impl Iterator<Item = f32>, leaving: u32) -> bool {
        let (k, r_min, r_max) = new.fold((0u32, f32::MAX, 0.0f32), |(k, a, b), r| {
            (k + 1, a.min(r), b.max(r))
        });
        let radii_fit = k == 0 || (r_min as f64 >= self.radii.0 && r_max as f64 <= self.radii.1);
        let ids_fit = self
            .next_id
            .checked_add(k)
            .is_some_and(|end| end <= FIRST_MESH_WALL);
        let rows = (self.n.saturating_sub(leaving)).checked_add(k);
        rows.is_some_and(|n| n <= self.capacity) && radii_fit && ids_fit
    }

    /// The state now holds `n` spheres: the dispatch and the uniform follow, and the next
    /// advance lays the grid out again, over the new bounds and count.
    pub(super) fn resize(&mut self, n: u32) {
        self.n = n;
        self.sort_next = true;
        self.counted = false;
        self.groups = self.res.gpu.grid(n, GROUP);
        self.write_count();
        self.stale = true;
    }

    /// Writes the sphere count and the dispatch rows into the step's parameters.
    pub(super) fn write_count(&mut self) {
        let (n, row) = (self.n, self.groups.0 * GROUP);
        self.res
            .dem_uniform
            .update(&self.res.gpu, |p| (p.n, p.row) = (n, row));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dem::Stepper;
    use crate::dem::model::{ContactLaw, LiquidBridge, Material};
    use crate::engines::DemSetup;
    use crate::gpu::test_gpu;

    const R: f32 = 1e-3;

    /// Water bridges of 1 nl between 1 mm spheres of a soft elastic material, in a 1 cm box.
    fn wet() -> StepParams {
        let material = Material {
            contact: ContactLaw::HertzMindlin {
                young_modulus: 1e7,
                poisson_ratio: 0.3,
            },
            density: 2500.0,
            restitution: 0.1,
            bridge: Some(LiquidBridge {
                volume: 1e-12,
                surface_tension: 0.072,
                contact_angle: 0.0,
                viscosity: 0.0,
            }),
            ..Material::default()
        };
        let side = [0.01; 3];
        let probe = StepParams::new(&material, 1e-9, [0.0; 3], side, [0.0; 3], 0.0, R).unwrap();
        let dt = 0.5 * probe.dt_limit as f64;
        StepParams::new(&material, dt, [0.0; 3], side, [0.0; 3], 0.0, R).unwrap()
    }

    /// Two spheres a hair into each other about the box's centre, flying apart along x.
    fn flying_apart() -> [NewSphere; 2] {
        [-1.0f32, 1.0].map(|side| NewSphere {
            centre: [0.005 + side * (R - 1e-7), 0.005, 0.005],
            velocity: [side * 0.3, 0.0, 0.0],
            radius: R,
            material: 0,
        })
    }

    /// Two spheres alone in corners of the box.
    fn apart() -> Particles {
        Particles {
            positions: vec![[0.0015; 3], [0.0085; 3]],
            velocities: vec![[0.0; 3]; 2],
            angular_velocities: vec![[0.0; 3]; 2],
            radii: vec![R; 2],
            ..Particles::default()
        }
    }

    /// The step of `particles` under `p` on `gpu`, with room for `spheres`.
    fn step(gpu: &Gpu, particles: Particles, p: &StepParams, spheres: usize) -> GridStepper {
        let room = Room {
            spheres,
            radii: (R, R),
            region: None,
        };
        let setup = DemSetup::new(particles, p.clone(), crate::ProxyMode::Mochi);
        GridStepper::flowing_on(gpu.clone(), setup, room, GridStepOptions::default()).unwrap()
    }

    #[test]
    fn spheres_appended_past_the_opening_ids_hold_their_bridges_across_a_gap() {
        // Opened over two spheres with room for eight, the step names stable ids below eight
        // by their places; six spheres come and go, and the two appended then (ids 8 and 9)
        // fly apart bonded by a bridge: the names grow to hold them, and the bridge pulls
        // across the gap as in a step that held the pair from the start.
        let Some(gpu) = test_gpu("spheres appended past the opening's ids") else {
            return;
        };
        let p = wet();
        let mut grown = step(&gpu, apart(), &p, 8);
        let passing: Vec<NewSphere> = (0..6)
            .map(|k| NewSphere {
                centre: [0.0015 + 0.0012 * k as f32, 0.0085, 0.0015],
                velocity: [0.0; 3],
                radius: R,
                material: 0,
            })
            .collect();
        assert!(grown.append(&passing).unwrap());
        grown.advance(1).unwrap();
        assert!(grown.remove(&[2, 3, 4, 5, 6, 7]).unwrap());
        assert!(grown.append(&flying_apart()).unwrap());
        assert_eq!(grown.next_id, 10);

        let mut whole = apart();
        for s in flying_apart() {
            whole.positions.push(s.centre);
            whole.velocities.push(s.velocity);
            whole.angular_velocities.push([0.0; 3]);
            whole.radii.push(s.radius);
        }
        let mut held = step(&gpu, whole, &p, 8);
        // The pair parts by 13 µm a step: apart after one, ruptured (at 100 µm) after eight.
        for k in 0..6 {
            let (a, b) = (grown.advance(1).unwrap(), held.advance(1).unwrap());
            assert_eq!(a.contacts, 1, "step {k}");
            assert_eq!(b.contacts, 1, "step {k}");
        }
        let pulled = |s: &mut GridStepper| s.particles().unwrap().velocities[3][0];
        let (went, reference) = (pulled(&mut grown), pulled(&mut held));
        assert!(
            reference < 0.3 - 1e-4,
            "the bridge did not pull: {reference} m/s"
        );
        assert!(
            (went - reference).abs() <= 1e-6 * reference.abs(),
            "{went} m/s against {reference} m/s"
        );
    }
}
