//! Paced replay on paused tokio time: deadlines, speed, seek, looping, lost frames.

use glam::Vec3;
use mimic_capture::{Pace, RecordedFrame, Replay, ReplayOptions, ReplayStart};
use mimic_types::LandmarkFrame;
use std::time::Duration;
use tokio::time::Instant;

/// Frames at the given timestamps (µs); the frame at `lost` has lost tracking.
fn frames(ts: &[i64], lost: Option<i64>) -> Vec<RecordedFrame> {
    ts.iter()
        .map(|&t| {
            let mut f = LandmarkFrame::new(t, vec![Vec3::splat(t as f32 * 1e-6)]);
            if Some(t) == lost {
                f = LandmarkFrame {
                    timestamp_us: t,
                    points: vec![],
                    valid: vec![],
                    tracked: false,
                };
            }
            RecordedFrame {
                frame: f,
                label: Some(t % 2),
            }
        })
        .collect()
}

/// tokio's timer wheel has 1 ms resolution: a deadline fires at most 1 ms late, never early.
const TIMER_RESOLUTION: Duration = Duration::from_millis(1);

#[tokio::test(start_paused = true)]
async fn frames_come_at_their_recorded_times_without_drift() {
    // 500 frames with jittery gaps (63 ms ± up to 40 ms, in µs), like the GFE recordings.
    let mut ts = vec![1_390_385_014_756_000i64];
    for k in 1..500 {
        ts.push(ts[k - 1] + 63_000 + ((k as i64 * 7919) % 81 - 40) * 1000 + 123);
    }
    let mut r =
        Replay::from_frames(frames(&ts, Some(ts[10])), 16.0, ReplayOptions::default()).unwrap();
    let start = Instant::now();
    let mut n = 0;
    while let Some(f) = r.next().await {
        let f = f.unwrap();
        let elapsed = start.elapsed();
        let due = Duration::from_micros((ts[n] - ts[0]) as u64);
        assert!(
            elapsed >= due && elapsed <= due + TIMER_RESOLUTION,
            "frame {n}: {elapsed:?} vs {due:?}"
        );
        assert_eq!(f.frame.timestamp_us, ts[n]);
        assert_eq!(
            f.frame.tracked,
            n != 10,
            "lost-tracking frame passed on as such"
        );
        n += 1;
    }
    assert_eq!(n, 500);
}

#[tokio::test(start_paused = true)]
async fn speed_factor_scales_the_waits_and_unpaced_does_not_wait() {
    let ts = [0, 100_000, 300_000, 1_000_000];
    let opts = ReplayOptions {
        pace: Pace::Recorded { speed: 4.0 },
        ..Default::default()
    };
    let mut r = Replay::from_frames(frames(&ts, None), 10.0, opts).unwrap();
    let start = Instant::now();
    let mut times = Vec::new();
    while let Some(f) = r.next().await {
        f.unwrap();
        times.push(start.elapsed());
    }
    // Due at t / 4: 0, 25, 75, 250 ms (each within the timer resolution).
    let want = [0, 25, 75, 250].map(Duration::from_millis);
    for (got, want) in times.iter().zip(want) {
        assert!(
            *got >= want && *got <= want + TIMER_RESOLUTION,
            "{got:?} vs {want:?}"
        );
    }
    let opts = ReplayOptions {
        pace: Pace::AsFastAsPossible,
        ..Default::default()
    };
    let mut r = Replay::from_frames(frames(&ts, None), 10.0, opts).unwrap();
    let start = Instant::now();
    let mut n = 0;
    while r.next().await.is_some() {
        n += 1;
    }
    assert_eq!((n, start.elapsed()), (4, Duration::ZERO));
    assert!(
        Replay::from_frames(
            vec![],
            10.0,
            ReplayOptions {
                pace: Pace::Recorded { speed: 0.0 },
                ..Default::default()
            }
        )
        .is_err()
    );
}

#[tokio::test(start_paused = true)]
async fn nothing_is_handed_out_before_it_is_due() {
    let ts = [0, 500_000];
    let mut r = Replay::from_frames(frames(&ts, None), 2.0, ReplayOptions::default()).unwrap();
    assert_eq!(r.next().await.unwrap().unwrap().frame.timestamp_us, 0);
    // 499 ms later the second frame is still not due: a timeout of 499 ms elapses first.
    let early = tokio::time::timeout(Duration::from_millis(499), r.next()).await;
    assert!(early.is_err());
    // The frame taken from the source was kept (cancel-safe) and comes once due.
    tokio::time::advance(Duration::from_millis(1)).await;
    let f = r.next().await.unwrap().unwrap();
    assert_eq!(f.frame.timestamp_us, 500_000);
}

#[tokio::test(start_paused = true)]
async fn seek_starts_at_the_first_frame_at_or_after_the_time() {
    let ts = [1_000, 2_000, 3_000, 4_000, 5_000];
    let opts = ReplayOptions {
        start: ReplayStart::Timestamp(2_500),
        pace: Pace::AsFastAsPossible,
        looping: false,
    };
    let mut r = Replay::from_frames(frames(&ts, None), 1000.0, opts).unwrap();
    let mut got = Vec::new();
    while let Some(f) = r.next().await {
        got.push(f.unwrap().frame.timestamp_us);
    }
    assert_eq!(got, vec![3_000, 4_000, 5_000]);
    // By offset from the first frame: 1 ms + 3 ms = 4 ms; paced from that frame, so no initial wait.
    let opts = ReplayOptions {
        start: ReplayStart::Offset(Duration::from_micros(3_000)),
        ..Default::default()
    };
    let mut r = Replay::from_frames(frames(&ts, None), 1000.0, opts).unwrap();
    let start = Instant::now();
    assert_eq!(r.next().await.unwrap().unwrap().frame.timestamp_us, 4_000);
    assert_eq!(start.elapsed(), Duration::ZERO);
}

#[tokio::test(start_paused = true)]
async fn looping_restarts_from_the_beginning_with_increasing_timestamps() {
    let ts = [100_000, 200_000, 400_000];
    let opts = ReplayOptions {
        looping: true,
        start: ReplayStart::Timestamp(200_000),
        ..Default::default()
    };
    // Rate 10 Hz: passes are joined by a 100 ms gap.
    let mut r = Replay::from_frames(frames(&ts, None), 10.0, opts).unwrap();
    let start = Instant::now();
    let mut got = Vec::new();
    for _ in 0..8 {
        let f = r.next().await.unwrap().unwrap();
        got.push((f.frame.timestamp_us, f.recorded_us, f.pass, f.label));
        let due = Duration::from_micros((f.frame.timestamp_us - 200_000) as u64);
        let e = start.elapsed();
        assert!(e >= due && e <= due + TIMER_RESOLUTION, "{e:?} vs {due:?}");
    }
    // Pass 0 from the seek point; pass 1 starts at 400 + 100 ms, each pass spans 300 + 100 ms.
    let want = vec![
        (200_000, 200_000, 0, Some(0)),
        (400_000, 400_000, 0, Some(0)),
        (500_000, 100_000, 1, Some(0)),
        (600_000, 200_000, 1, Some(0)),
        (800_000, 400_000, 1, Some(0)),
        (900_000, 100_000, 2, Some(0)),
        (1_000_000, 200_000, 2, Some(0)),
        (1_200_000, 400_000, 2, Some(0)),
    ];
    assert_eq!(got, want);
    // An empty source ends instead of spinning.
    let mut r = Replay::from_frames(
        vec![],
        10.0,
        ReplayOptions {
            looping: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(r.next().await.is_none());
}

#[tokio::test(start_paused = true)]
async fn file_replay_skips_rejected_lines_and_loops_by_reopening() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("r.jsonl");
    let header = r#"{"format":"mimic-recording","version":1,"layout":"one","units":"m","source":"t","rate_hz":20.0}"#;
    let text = format!(
        "{header}\n{}\n{}\n{}\n{}\n",
        r#"{"t_us":0,"points":[[0,0,0]]}"#,
        r#"{"t_us":50000,"points":[],"tracked":false}"#,
        r#"{"t_us":60000,"points":[[0,0,0],[1,1,1]]}"#,
        r#"{"t_us":100000,"points":[[0,0,1]]}"#
    );
    std::fs::write(&path, text).unwrap();
    let opts = ReplayOptions {
        looping: true,
        ..Default::default()
    };
    let mut r = Replay::open(&path, None, opts).unwrap();
    let mut got = Vec::new();
    for _ in 0..6 {
        let f = r.next().await.unwrap().unwrap();
        got.push((f.frame.timestamp_us, f.frame.tracked));
    }
    // 20 Hz: 50 ms between passes; the 2-point frame is rejected on each pass.
    assert_eq!(
        got,
        vec![
            (0, true),
            (50_000, false),
            (100_000, true),
            (150_000, true),
            (200_000, false),
            (250_000, true)
        ]
    );
    assert_eq!(r.skipped(), 2);
}

#[tokio::test(start_paused = true)]
async fn a_real_gfe_recording_replays_in_its_recorded_duration() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../recordings/a_affirmative.jsonl");
    let opts = ReplayOptions {
        pace: Pace::Recorded { speed: 2.0 },
        ..Default::default()
    };
    let mut r = Replay::open(&path, Some(100), opts).unwrap();
    let start = Instant::now();
    let (mut n, mut first, mut last) = (0, None, 0);
    while let Some(f) = r.next().await {
        let f = f.unwrap();
        let t0 = *first.get_or_insert(f.frame.timestamp_us);
        last = f.frame.timestamp_us;
        // Each frame at (t - t0) / 2, never early, at most one timer tick late: no drift over 1062 frames.
        let due = Duration::from_micros(((last - t0) as f64 / 2.0).round() as u64);
        let e = start.elapsed();
        assert!(
            e >= due && e <= due + TIMER_RESOLUTION,
            "frame {n}: {e:?} vs {due:?}"
        );
        n += 1;
    }
    assert_eq!(n, 1062);
    // 69.0 s recorded (dataset notes) at double speed: about 34.5 s of (paused) tokio time.
    let span_s = (last - first.unwrap()) as f64 * 1e-6;
    assert!((span_s - 69.0).abs() < 0.05, "{span_s}");
    assert_eq!(r.skipped(), 0);
}
