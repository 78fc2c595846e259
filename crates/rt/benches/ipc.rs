//! IPC costs on one thread (no contention): mailbox put+get, ring push+pop, semaphore
//! signal+take.

// criterion_group! and criterion_main! make public functions without docs.
#![allow(missing_docs)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use rtcnc_rt::{BinarySemaphore, Mailbox, ring};

fn ipc(c: &mut Criterion) {
    let mb: Mailbox<[f64; 4]> = Mailbox::new("bench", 64).unwrap();
    c.bench_function("mailbox try_put + try_get", |b| {
        b.iter(|| {
            mb.try_put(black_box([1.0, 2.0, 3.0, 4.0])).unwrap();
            black_box(mb.try_get())
        })
    });
    let (mut tx, mut rx) = ring::<[f64; 4]>("bench", 64).unwrap();
    c.bench_function("ring push + pop", |b| {
        b.iter(|| {
            tx.push(black_box([1.0, 2.0, 3.0, 4.0])).unwrap();
            black_box(rx.pop())
        })
    });
    let sem = BinarySemaphore::new("bench");
    c.bench_function("binary semaphore signal + try_wait", |b| {
        b.iter(|| {
            sem.signal();
            black_box(sem.try_wait())
        })
    });
}

criterion_group!(benches, ipc);
criterion_main!(benches);
