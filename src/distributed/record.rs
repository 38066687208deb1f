//! A sphere as the ranks of a decomposed run send and hold it: its id in the whole run, its
//! state and its contacts (partners by id), and the messages that carry such records.

use crate::Spheres;
use crate::detect::Backend;
use crate::engines::cpu::CpuBackend;
use crate::error::{Error, Result};
use crate::particles::{HistoryEntry, LoadEntry, Particles};
use crate::proxy::ProxyMode;
use rayon::prelude::*;

/// A sphere as a rank sends it: its id in the whole run and its state, followed in a message
/// by `contacts` history entries and `loads` load histories (none, or one a contact: the
/// Mindlin–Deresiewicz model's).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct SphereRecord {
    pub id: u32,
    pub material: u32,
    pub radius: f32,
    pub position: [f32; 3],
    pub residual: [f32; 3],
    pub velocity: [f32; 3],
    pub spin: [f32; 3],
    /// History entries and load histories following it in a message.
    pub contacts: u32,
    pub loads: u32,
}

impl SphereRecord {
    /// Where its centre is, in `f64`.
    pub fn exact_position(&self) -> [f64; 3] {
        std::array::from_fn(|a| {
            crate::particles::position::join(self.position[a], self.residual[a])
        })
    }

    /// Its speed \[m/s\].
    pub fn speed(&self) -> f64 {
        let squares = self.velocity.iter().map(|&v| (v as f64).powi(2));
        squares.sum::<f64>().sqrt()
    }
}

/// A sphere a rank owns: its state and its contacts (partners by id), with their load
/// histories where the run keeps them.
#[derive(Debug, Clone)]
pub(super) struct Held {
    pub sphere: SphereRecord,
    pub contacts: Vec<HistoryEntry>,
    pub loads: Vec<LoadEntry>,
}

impl Held {
    /// Sphere `at` of `p` as sphere `id` of the whole run, its partners renamed by `rename`.
    pub fn of(
        p: &Particles,
        at: usize,
        id: u32,
        rename: impl Fn(&HistoryEntry) -> HistoryEntry,
    ) -> Self {
        Held {
            sphere: record_of(p, at, id),
            contacts: p.history.of(at).iter().map(rename).collect(),
            loads: p.history.loads_of(at).to_vec(),
        }
    }

    /// Sphere `at` of `p` as the sphere of that id in the whole run, with `contacts` and their
    /// `loads` (none, or one a contact) for its history.
    pub fn with_history(
        p: &Particles,
        at: usize,
        contacts: Vec<HistoryEntry>,
        loads: Vec<LoadEntry>,
    ) -> Self {
        Held {
            sphere: record_of(p, at, at as u32),
            contacts,
            loads,
        }
    }

    /// Where its centre is, in `f64`.
    pub fn exact_position(&self) -> [f64; 3] {
        self.sphere.exact_position()
    }
}

/// The contacts of the own spheres of `p` (at the places `own_at`, ascending) with any sphere
/// of it, as the cpu step's per-sphere counts sum them (a contact of two own spheres counted by
/// both; two components of one clump are never a contact): its touching pairs, found on the
/// host.
pub(super) fn own_pair_ends(p: &Particles, own_at: &[usize], mode: ProxyMode) -> Result<u64> {
    let mut backend = CpuBackend::new();
    backend.build(Spheres::check(&p.positions, &p.radii)?, mode)?;
    let (pairs, _) = backend.find_pairs()?;
    let clump_of = p.clumps.owners();
    let one_clump = |i: u32, j: u32| match (clump_of.get(i as usize), clump_of.get(j as usize)) {
        (Some(a), Some(b)) => a == b,
        _ => false,
    };
    let own = |at: u32| own_at.binary_search(&(at as usize)).is_ok() as u64;
    Ok((pairs.iter())
        .filter(|pair| !one_clump(pair.i, pair.j))
        .map(|pair| own(pair.i) + own(pair.j))
        .sum())
}

/// A history entry of spheres whose whole-run ids are `ids` (by place) with its partner
/// named by its whole-run id instead of its place (a wall keeps its own).
pub(super) fn partners_by_id(ids: &[u32]) -> impl Fn(&HistoryEntry) -> HistoryEntry + Copy + '_ {
    let n = ids.len() as u32;
    move |e| HistoryEntry {
        partner: match e.partner < n {
            true => ids[e.partner as usize],
            false => e.partner,
        },
        ..*e
    }
}

/// Sphere `i` of `p` as a record of id `id` (no contacts counted yet).
pub(super) fn record_of(p: &Particles, i: usize, id: u32) -> SphereRecord {
    SphereRecord {
        id,
        material: p.material(i),
        radius: p.radii[i],
        position: p.positions[i],
        residual: p.residual(i),
        velocity: p.velocities[i],
        spin: p.angular_velocities[i],
        contacts: 0,
        loads: 0,
    }
}

/// Appends `sphere`, its contacts and their load histories to `message`.
pub(super) fn put(
    message: &mut Vec<u8>,
    sphere: &SphereRecord,
    (contacts, loads): (&[HistoryEntry], &[LoadEntry]),
) {
    let record = SphereRecord {
        contacts: contacts.len() as u32,
        loads: loads.len() as u32,
        ..*sphere
    };
    message.extend_from_slice(bytemuck::bytes_of(&record));
    message.extend_from_slice(bytemuck::cast_slice(contacts));
    message.extend_from_slice(bytemuck::cast_slice(loads));
}

/// The spheres of every message of `messages` ([`read`]), each message read on a thread of its
/// own, one message's after the other's.
pub(super) fn read_all(messages: &[Vec<u8>]) -> Result<Vec<Held>> {
    let parts: Vec<Vec<Held>> = (messages.par_iter())
        .map(|m| read(m))
        .collect::<Result<_>>()?;
    let mut all = Vec::with_capacity(parts.iter().map(Vec::len).sum());
    parts.into_iter().for_each(|part| all.extend(part));
    Ok(all)
}

/// The spheres of a message [`put`] wrote.
pub(super) fn read(message: &[u8]) -> Result<Vec<Held>> {
    // At most a sphere a record's bytes: room for every one at once.
    let mut out = Vec::with_capacity(message.len() / std::mem::size_of::<SphereRecord>());
    let mut rest = message;
    // The next `bytes` bytes of the message.
    fn cut<'a>(rest: &mut &'a [u8], bytes: usize) -> Result<&'a [u8]> {
        if rest.len() < bytes {
            return Err(Error::Usage("a rank's message ends inside a sphere".into()));
        }
        let (head, tail) = rest.split_at(bytes);
        *rest = tail;
        Ok(head)
    }
    // The next `count` values of type T.
    fn values<T: bytemuck::Pod>(rest: &mut &[u8], count: u32) -> Result<Vec<T>> {
        let size = std::mem::size_of::<T>();
        let body = cut(rest, count as usize * size)?;
        Ok(body
            .chunks_exact(size)
            .map(bytemuck::pod_read_unaligned)
            .collect())
    }
    while !rest.is_empty() {
        let head = cut(&mut rest, std::mem::size_of::<SphereRecord>())?;
        let sphere: SphereRecord = bytemuck::pod_read_unaligned(head);
        let contacts = values(&mut rest, sphere.contacts)?;
        let loads = values(&mut rest, sphere.loads)?;
        out.push(Held {
            sphere: SphereRecord {
                contacts: 0,
                loads: 0,
                ..sphere
            },
            contacts,
            loads,
        });
    }
    Ok(out)
}

/// The spheres of `items` (each one's record by `sphere`), in their order, at step `step` (no
/// contact history yet).
pub(super) fn spheres_of<T: Sync>(
    items: &[T],
    sphere: impl Fn(&T) -> &SphereRecord + Sync,
    step: u64,
) -> Particles {
    let column =
        |of: fn(&SphereRecord) -> [f32; 3]| items.par_iter().map(|t| of(sphere(t))).collect();
    let mut p = Particles {
        positions: column(|s| s.position),
        position_residuals: column(|s| s.residual),
        velocities: column(|s| s.velocity),
        angular_velocities: column(|s| s.spin),
        radii: items.par_iter().map(|t| sphere(t).radius).collect(),
        materials: items.par_iter().map(|t| sphere(t).material as u8).collect(),
        step,
        ..Particles::default()
    };
    // Every sphere of the first material: the list left empty, as a run of one keeps it.
    if p.materials.iter().all(|&m| m == 0) {
        p.materials.clear();
    }
    p
}
