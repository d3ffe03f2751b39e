//! Reading and writing v1 recordings: a real 1390-frame, 100-point GFE recording, in memory.

#![allow(
    clippy::unwrap_used,
    reason = "a bench: a failed unwrap is the failure report"
)]

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use mimic_capture::{RecordedFrame, RecordingReader, RecordingWriter};
use std::hint::black_box;
use std::io::Cursor;
use std::path::Path;

fn bench(c: &mut Criterion) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../recordings/a_yn_question.jsonl");
    let bytes = std::fs::read(&path).expect("shipped recording");
    let reader =
        RecordingReader::new(Cursor::new(bytes.clone()), &path, Some(100)).expect("header");
    let header = reader.header().clone();
    // Debug builds (cargo test --benches) use 100 frames to stay quick.
    let keep = if cfg!(debug_assertions) {
        100
    } else {
        usize::MAX
    };
    let frames: Vec<RecordedFrame> = reader.filter_map(Result::ok).take(keep).collect();
    let mut text = Vec::new();
    let mut w = RecordingWriter::new(&mut text, &header).expect("header");
    for f in &frames {
        w.write(f).expect("frame");
    }
    w.finish().expect("flush");

    let mut g = c.benchmark_group("recording");
    g.throughput(Throughput::Elements(frames.len() as u64));
    g.bench_function("read_gfe100", |b| {
        b.iter(|| {
            let r = RecordingReader::new(Cursor::new(black_box(&text[..])), "bench", Some(100))
                .expect("header");
            r.filter(Result::is_ok).count()
        })
    });
    g.bench_function("write_gfe100", |b| {
        let mut out = Vec::with_capacity(text.len());
        b.iter(|| {
            out.clear();
            let mut w = RecordingWriter::new(&mut out, &header).expect("header");
            for f in &frames {
                w.write(black_box(f)).expect("frame");
            }
            w.finish().expect("flush");
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
