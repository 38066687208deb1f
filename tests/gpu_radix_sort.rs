//! The GPU radix sort against a stable CPU sort, on a real adapter (lavapipe in CI).
//!
//! Without an adapter the tests print why and pass, except under `CI=true`, where they fail.

mod common;

use mochi::gpu::Gpu;
use mochi::gpu::radix_sort::{BLOCK, RadixSort};
use rand::{Rng, RngExt, SeedableRng};
use rand_pcg::Pcg64;
use std::time::Instant;

/// A pair buffer holding `data` (STORAGE | COPY_SRC | COPY_DST).
fn upload(gpu: &Gpu, label: &str, data: &[u32]) -> wgpu::Buffer {
    let buffer = gpu.storage(label, (data.len() * 4) as u64, wgpu::BufferUsages::empty());
    gpu.queue
        .write_buffer(&buffer, 0, bytemuck::cast_slice(data));
    buffer
}

/// `keys` by the low `key_bits` bits, with values = original index, sorted stably on the CPU.
fn cpu_sort(keys: &[u32], key_bits: u32) -> (Vec<u32>, Vec<u32>) {
    let mask = if key_bits >= 32 {
        u32::MAX
    } else {
        (1u32 << key_bits) - 1
    };
    let mut order: Vec<u32> = (0..keys.len() as u32).collect();
    order.sort_by_key(|&i| keys[i as usize] & mask); // stable
    (order.iter().map(|&i| keys[i as usize]).collect(), order)
}

/// Sorts `keys` (values = original index) on the GPU and returns the sorted keys and values.
fn gpu_sort(gpu: &Gpu, sort: &mut RadixSort, keys: &[u32], key_bits: u32) -> (Vec<u32>, Vec<u32>) {
    let values: Vec<u32> = (0..keys.len() as u32).collect();
    let n = keys.len() as u32;
    let (k, v) = gpu
        .checked("radix sort", || {
            let k = upload(gpu, "test.keys", keys);
            let v = upload(gpu, "test.values", &values);
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            sort.encode(gpu, &mut encoder, &k, &v, n, key_bits);
            gpu.queue.submit([encoder.finish()]);
            (k, v)
        })
        .expect("no GPU error");
    let k = gpu.read::<u32>(&k, keys.len()).expect("read keys");
    let v = gpu.read::<u32>(&v, keys.len()).expect("read values");
    (k, v)
}

/// Sorts `n` zero keys, which this device cannot: the sort must report an error.
fn check_refused(gpu: &Gpu, sort: &mut RadixSort, n: usize) {
    let result = gpu.checked("radix sort", || {
        let k = upload(gpu, "test.keys", &vec![0; n]);
        let v = upload(gpu, "test.values", &vec![0; n]);
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        sort.encode(gpu, &mut encoder, &k, &v, n as u32, 32);
        gpu.queue.submit([encoder.finish()]);
    });
    assert!(
        result.is_err(),
        "n = {n} is over this device's limits, yet no error"
    );
    eprintln!("n = {n}: refused ({})", result.err().unwrap());
}

/// Sorts on both sides and compares keys and values exactly (values prove stability).
fn check(gpu: &Gpu, sort: &mut RadixSort, what: &str, keys: &[u32], key_bits: u32) {
    let start = Instant::now();
    let (gk, gv) = gpu_sort(gpu, sort, keys, key_bits);
    let took = start.elapsed();
    let (ck, cv) = cpu_sort(keys, key_bits);
    assert_eq!(gk.len(), ck.len());
    if let Some(i) = (0..ck.len()).find(|&i| gk[i] != ck[i] || gv[i] != cv[i]) {
        panic!(
            "{what}, n = {}, key_bits = {key_bits}: first difference at {i}: \
             gpu ({:#x}, {}) vs cpu ({:#x}, {})",
            keys.len(),
            gk[i],
            gv[i],
            ck[i],
            cv[i]
        );
    }
    eprintln!(
        "{what}: n = {}, key_bits = {key_bits}: ok in {took:.2?}",
        keys.len()
    );
}

fn random_keys(n: usize, seed: u64) -> Vec<u32> {
    let mut rng = Pcg64::seed_from_u64(seed);
    (0..n).map(|_| rng.next_u32()).collect()
}

#[test]
fn random_keys_small_and_medium() {
    let Some(gpu) = common::open_gpu("the GPU radix sort") else {
        return;
    };
    let mut sort = RadixSort::new(&gpu);
    for (seed, n) in [0usize, 1, 7, 256, 257, 2048, 2049, 4097, 100_000]
        .into_iter()
        .enumerate()
    {
        let keys = random_keys(n, seed as u64);
        for key_bits in [30, 32, 8, 20, 1] {
            check(&gpu, &mut sort, "random", &keys, key_bits);
        }
    }
}

/// Workgroups per dimension of the device of [`two_d_grids_within_a_lowered_limit`].
const LOWERED: u32 = 64;

#[test]
fn two_d_grids_within_a_lowered_limit() {
    let Some(gpu) = common::open_gpu_lowered("the GPU radix sort's 2-D grids", LOWERED) else {
        return;
    };
    assert_eq!(gpu.limits.max_compute_workgroups_per_dimension, LOWERED);
    let mut sort = RadixSort::new(&gpu);
    // 65 and 147 blocks: rows of 64 workgroups (the device rejects a wider dispatch, so a 1-D
    // one would fail).
    for n in [64 * BLOCK as usize + 1, 300_007] {
        let keys = random_keys(n, n as u64);
        for key_bits in [32, 8] {
            check(&gpu, &mut sort, "2-D", &keys, key_bits);
        }
    }
    // 64 × 64 blocks are the most one dispatch takes here; one key more is an error.
    check_refused(&gpu, &mut sort, (LOWERED * LOWERED * BLOCK) as usize + 1);
}

#[test]
fn random_keys_large() {
    let Some(gpu) = common::open_gpu("the GPU radix sort") else {
        return;
    };
    let mut sort = RadixSort::new(&gpu);
    let keys = random_keys(1_000_003, 42);
    for key_bits in [30, 32, 8] {
        check(&gpu, &mut sort, "random", &keys, key_bits);
    }
}

#[test]
fn few_distinct_keys_are_stable() {
    let Some(gpu) = common::open_gpu("the GPU radix sort") else {
        return;
    };
    let mut sort = RadixSort::new(&gpu);
    let mut rng = Pcg64::seed_from_u64(7);
    let keys: Vec<u32> = (0..50_000)
        .map(|_| rng.random_range(0..5u32) << 13)
        .collect();
    check(&gpu, &mut sort, "five keys", &keys, 16);
    let n = 100_000u32;
    check(
        &gpu,
        &mut sort,
        "all equal",
        &vec![0xdead_beef; n as usize],
        32,
    );
    let sorted: Vec<u32> = (0..n).map(|i| i * 7).collect();
    check(&gpu, &mut sort, "sorted", &sorted, 32);
    let reverse: Vec<u32> = (0..n).rev().collect();
    check(&gpu, &mut sort, "reverse", &reverse, 17);
    // Garbage above key_bits must not take part: only the low 8 bits order these.
    let garbage: Vec<u32> = (0..n)
        .map(|i| (i.wrapping_mul(2_654_435_761) << 8) | (255 - i % 256))
        .collect();
    check(&gpu, &mut sort, "garbage above key_bits", &garbage, 8);
}

#[test]
fn several_sorts_in_one_submit() {
    let Some(gpu) = common::open_gpu("the GPU radix sort") else {
        return;
    };
    let mut sort = RadixSort::new(&gpu);
    let a = random_keys(70_000, 1);
    let b = random_keys(5_000, 2);
    let index = |n: usize| (0..n as u32).collect::<Vec<u32>>();
    let (ka, va, kb, vb) = gpu
        .checked("two sorts, one submit", || {
            let ka = upload(&gpu, "test.a.keys", &a);
            let va = upload(&gpu, "test.a.values", &index(a.len()));
            let kb = upload(&gpu, "test.b.keys", &b);
            let vb = upload(&gpu, "test.b.values", &index(b.len()));
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            // Different sizes and key widths (8 passes, then 3): they share the scratch buffers,
            // each keeps its own parameters.
            sort.encode(&gpu, &mut encoder, &ka, &va, a.len() as u32, 32);
            sort.encode(&gpu, &mut encoder, &kb, &vb, b.len() as u32, 12);
            gpu.queue.submit([encoder.finish()]);
            (ka, va, kb, vb)
        })
        .expect("no GPU error");
    let read = |buf: &wgpu::Buffer, n: usize| gpu.read::<u32>(buf, n).expect("read back");
    assert_eq!(
        (read(&ka, a.len()), read(&va, a.len())),
        cpu_sort(&a, 32),
        "first sort"
    );
    assert_eq!(
        (read(&kb, b.len()), read(&vb, b.len())),
        cpu_sort(&b, 12),
        "second sort"
    );
}

/// Checks in O(n) that (`keys`, `values`) is the stable sort of `input` (values = original index)
/// by the low `key_bits` bits: values form a permutation, each key is its input key, and
/// neighbours are in (masked key, index) order.
fn assert_stable_sort_of(input: &[u32], keys: &[u32], values: &[u32], key_bits: u32) {
    let mask = if key_bits >= 32 {
        u32::MAX
    } else {
        (1u32 << key_bits) - 1
    };
    let n = input.len();
    assert_eq!((keys.len(), values.len()), (n, n));
    let mut seen = vec![false; n];
    for (i, (&k, &v)) in keys.iter().zip(values).enumerate() {
        let v = v as usize;
        assert!(v < n && !seen[v], "values are not a permutation (at {i})");
        seen[v] = true;
        assert_eq!(k, input[v], "key at {i} is not the input key of value {v}");
        if i > 0 {
            let before = (keys[i - 1] & mask, values[i - 1]);
            assert!(before < (k & mask, v as u32), "not stably sorted at {i}");
        }
    }
}

/// Sizes a discrete GPU handles (16M pairs, and over 65535 sort blocks for the 2-D dispatch),
/// with wall-clock timings of record + submit + wait (a 2 × 4n-byte restore copy included).
#[test]
#[ignore = "needs a discrete GPU with a few GB free; run with --ignored"]
fn large_sizes_on_a_discrete_gpu() {
    let Some(gpu) = common::open_gpu("the GPU radix sort") else {
        return;
    };
    eprintln!("adapter: {}", mochi::gpu::describe(&gpu.info));
    if gpu.info.device_type == wgpu::DeviceType::Cpu {
        eprintln!("note: large sizes are not run on a CPU adapter");
        return;
    }
    let mut sort = RadixSort::new(&gpu);
    for n in [1usize << 20, 16_000_000, 140_000_000] {
        let bytes = n as u64 * 4;
        if bytes > gpu.limits.max_storage_buffer_binding_size || bytes > gpu.limits.max_buffer_size
        {
            check_refused(&gpu, &mut sort, n);
            continue;
        }
        let input = random_keys(n, n as u64);
        let index: Vec<u32> = (0..n as u32).collect();
        let none = wgpu::BufferUsages::empty();
        let (pk, pv, k, v) = gpu
            .checked("upload", || {
                (
                    upload(&gpu, "test.pristine_keys", &input),
                    upload(&gpu, "test.pristine_values", &index),
                    gpu.storage("test.keys", bytes, none),
                    gpu.storage("test.values", bytes, none),
                )
            })
            .expect("no GPU error");
        for key_bits in [32, 30, 8] {
            let mut times = Vec::new();
            for _ in 0..5 {
                let start = Instant::now();
                gpu.checked("sort", || {
                    let mut encoder = gpu.device.create_command_encoder(&Default::default());
                    encoder.copy_buffer_to_buffer(&pk, 0, &k, 0, bytes);
                    encoder.copy_buffer_to_buffer(&pv, 0, &v, 0, bytes);
                    sort.encode(&gpu, &mut encoder, &k, &v, n as u32, key_bits);
                    gpu.queue.submit([encoder.finish()]);
                    gpu.device
                        .poll(wgpu::PollType::wait_indefinitely())
                        .expect("GPU finished");
                })
                .expect("no GPU error");
                times.push(start.elapsed().as_secs_f64() * 1e3);
            }
            let keys = gpu.read::<u32>(&k, n).expect("read keys");
            let values = gpu.read::<u32>(&v, n).expect("read values");
            assert_stable_sort_of(&input, &keys, &values, key_bits);
            let mut warm = times[1..].to_vec();
            warm.sort_by(f64::total_cmp);
            eprintln!(
                "n = {n}, key_bits = {key_bits}: ok; first {:.2} ms, warm median {:.2} ms \
                 ({:.0} Mpairs/s)",
                times[0],
                warm[warm.len() / 2],
                n as f64 / warm[warm.len() / 2] / 1e3
            );
        }
    }
}
