//! GPU tests of the overlay (lavapipe on CI): text, a panel and the heat map's legend composited
//! over a rendered square land where their layout says, in the colours the CPU compositor
//! (`Overlay::paint`) gives, and leave every other pixel exactly as drawn without them.
//!
//! With no adapter these fail with the renderer's message, unless MIMIC_SKIP_GPU_TESTS is set.

#![allow(
    clippy::unwrap_used,
    reason = "a test: a failed unwrap is the failure report"
)]

use glam::Vec3;
use mimic_render::overlay::{self, TEXT, heat_color, legend_ticks, linear_to_srgb};
use mimic_render::{Anchor, Camera, Deform, Image, Overlay, Shading, View};

mod common;
use common::renderer;

fn px(img: &Image, x: i32, y: i32) -> [u8; 4] {
    let at = (y as usize * img.width as usize + x as usize) * 4;
    img.rgba[at..at + 4].try_into().unwrap()
}

fn srgb(c: [f32; 3]) -> [u8; 3] {
    c.map(linear_to_srgb)
}

/// Largest channel difference of two pixels.
fn diff(a: [u8; 4], b: [u8; 4]) -> u8 {
    (0..4).map(|c| a[c].abs_diff(b[c])).max().unwrap_or(0)
}

/// One level of sRGB rounding between the GPU's blend and the CPU's, plus one for the GPU's own
/// rounding of the ramp's interpolation: at most 2 per channel.
const LEVELS: u8 = 2;

#[test]
fn the_overlay_lands_in_its_rectangles_and_nowhere_else() {
    let (w, h) = (192u32, 144u32);
    let Some(r) = renderer(w, h) else {
        return;
    };
    // A square filling most of the view, heat-mapped at rest (all of it the ramp's cold end).
    let p = vec![
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, -1.0, 0.0),
        Vec3::new(-1.0, 1.0, 0.0),
        Vec3::new(1.0, 1.0, 0.0),
    ];
    let gpu = r.upload_rig(&p, &[[0, 1, 2], [2, 1, 3]], None).unwrap();
    let mut view = View::lit(Camera::framing(p[0], p[3], 0.0, 0.0));
    view.ambient = 1.0;
    view.shading = Shading::Displacement { full_scale: 1.0 };
    let plain = r.render(&gpu, Deform::Rest, &view).unwrap();

    let mut o = Overlay::new();
    let readout = o.text_panel(
        Anchor::TopLeft,
        (w, h),
        4,
        1,
        [("12.5 fps", TEXT), ("lat 3.1 ms", TEXT)].into_iter(),
    );
    let ticks = legend_ticks(Some(1.0), "cm");
    let legend = o.legend((w, h), 4, 1, "|u|", &ticks);
    let drawn = r.render_with(&gpu, Deform::Rest, &view, Some(&o)).unwrap();

    // Outside every quad's rectangle: the image without the overlay, exactly.
    let rects: Vec<_> = o.rects().collect();
    let mut outside = 0usize;
    for y in 0..h as i32 {
        for x in 0..w as i32 {
            if rects.iter().any(|q| q.contains(x, y)) {
                continue;
            }
            outside += 1;
            assert_eq!(px(&drawn, x, y), px(&plain, x, y), "({x}, {y}) outside");
        }
    }
    assert!(outside > (w * h) as usize / 2, "{outside} pixels outside");

    // Everywhere: the CPU compositing of the same overlay onto the plain image.
    let mut cpu = plain.clone();
    o.paint(&mut cpu);
    let mut worst = 0u8;
    for y in 0..h as i32 {
        for x in 0..w as i32 {
            worst = worst.max(diff(px(&drawn, x, y), px(&cpu, x, y)));
        }
    }
    assert!(
        worst <= LEVELS,
        "GPU vs CPU overlay differ by {worst} levels"
    );

    // The readout's text: its glyph pixels in the text colour, and they are there at all.
    let text = srgb([TEXT[0], TEXT[1], TEXT[2]]);
    let lit = (readout.y..readout.y + readout.h)
        .flat_map(|y| (readout.x..readout.x + readout.w).map(move |x| (x, y)))
        .filter(|&(x, y)| {
            let p = px(&drawn, x, y);
            (0..3).all(|c| p[c].abs_diff(text[c]) <= 1)
        })
        .count();
    // "12.5 fps" and "lat 3.1 ms": 16 glyphs of roughly 10-20 set font pixels each.
    assert!(lit > 16 * 8, "{lit} text pixels in the readout");

    // The legend's bar, row by row down its middle column: the ramp from hot (top) to cold.
    let bar = legend.bar;
    let mid = bar.x + bar.w / 2;
    let mut last_stop = usize::MAX;
    for y in bar.y..bar.y + bar.h {
        let t = ((bar.y + bar.h) as f32 - (y as f32 + 0.5)) / bar.h as f32;
        let want = srgb(heat_color(t));
        let got = px(&drawn, mid, y);
        let d = (0..3).map(|c| got[c].abs_diff(want[c])).max().unwrap();
        assert!(d <= LEVELS, "bar row {y} (t {t}): {got:?} vs {want:?}");
        // The nearest of the five stops never gets hotter going down.
        let stop = (0..5)
            .min_by_key(|&k| {
                let s = srgb(overlay::heat_color(k as f32 / 4.0));
                (0..3)
                    .map(|c| i32::from(got[c].abs_diff(s[c])))
                    .sum::<i32>()
            })
            .unwrap();
        assert!(stop <= last_stop, "row {y}: stop {stop} after {last_stop}");
        last_stop = stop;
    }
    assert_eq!(last_stop, 0, "the bar ends cold");
    let top = px(&drawn, mid, bar.y);
    assert!(top[0] > 180 && top[2] < 80, "the bar starts hot: {top:?}");
}

#[test]
fn an_empty_overlay_changes_nothing() {
    let Some(r) = renderer(64, 48) else {
        return;
    };
    let p = vec![
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, -1.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
    ];
    let gpu = r.upload_rig(&p, &[[0, 1, 2]], None).unwrap();
    let view = View::lit(Camera::framing(p[0], Vec3::new(1.0, 1.0, 0.0), 0.0, 0.0));
    let plain = r.render(&gpu, Deform::Rest, &view).unwrap();
    let with = r
        .render_with(&gpu, Deform::Rest, &view, Some(&Overlay::new()))
        .unwrap();
    assert_eq!(plain, with);
}
