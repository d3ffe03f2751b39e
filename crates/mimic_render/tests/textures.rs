//! GPU tests of textured drawing (lavapipe on CI): a square facing the camera, textured with four
//! coloured quadrants, lit by ambient light only, shows each quadrant's colour where it should.
//!
//! With no adapter these fail with the renderer's message, unless MIMIC_SKIP_GPU_TESTS is set.

#![allow(
    clippy::unwrap_used,
    reason = "a test: a failed unwrap is the failure report"
)]

use glam::Vec3;
use mimic_render::{Camera, Deform, Shading, View};
use mimic_types::{MeshTextures, TextureImage, TriangleTexture};

mod common;
use common::renderer;

/// Quadrant colours (sRGB bytes) of the 16 x 16 test texture: top-left, top-right, bottom-left,
/// bottom-right of the image.
const QUADRANTS: [[u8; 3]; 4] = [[230, 40, 30], [30, 200, 60], [40, 60, 220], [240, 220, 40]];

fn quadrant_texture() -> TextureImage {
    let n = 16u32;
    let rgba = (0..n)
        .flat_map(|y| {
            (0..n).flat_map(move |x| {
                let q = usize::from(x >= n / 2) + 2 * usize::from(y >= n / 2);
                let [r, g, b] = QUADRANTS[q];
                [r, g, b, 255]
            })
        })
        .collect();
    TextureImage {
        name: "quadrants.png".into(),
        width: n,
        height: n,
        rgba,
        encoded: Vec::new(),
        mime: "image/png",
    }
}

/// A unit square in the z = 0 plane facing +z: vertices bottom-left, bottom-right, top-left,
/// top-right; two triangles, counter-clockwise from +z.
fn square() -> (Vec<Vec3>, Vec<[u32; 3]>) {
    (
        vec![
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
        ],
        vec![[0, 1, 2], [2, 1, 3]],
    )
}

/// Image-convention UVs (v down) of the square's vertices: top-left of the square is (0, 0).
fn uv_of(v: u32) -> [f32; 2] {
    match v {
        0 => [0.0, 1.0],
        1 => [1.0, 1.0],
        2 => [0.0, 0.0],
        _ => [1.0, 0.0],
    }
}

/// A straight front view of the square, lit by ambient light alone: the drawn colour is the
/// albedo (or texel) unchanged.
fn flat_view() -> View {
    let mut view = View::lit(Camera::framing(
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, 1.0, 0.0),
        0.0,
        0.0,
    ));
    view.ambient = 1.0;
    view
}

#[test]
fn a_textured_square_shows_its_quadrants_upright() {
    let size = 128;
    let Some(r) = renderer(size, size) else {
        return;
    };
    let (p, tris) = square();
    let mut gpu = r.upload_rig(&p, &tris, None).unwrap();
    let textures = MeshTextures {
        textures: vec![quadrant_texture()],
        triangles: tris
            .iter()
            .map(|t| {
                Some(TriangleTexture {
                    texture: 0,
                    uv: [uv_of(t[0]), uv_of(t[1]), uv_of(t[2])],
                })
            })
            .collect(),
        materials: vec![vec![0]],
    };
    r.set_textures(&mut gpu, &textures).unwrap();
    assert!(gpu.is_textured());
    let img = r.render(&gpu, Deform::Rest, &flat_view()).unwrap();
    // The square spans the middle of the image; sample the centre of each quadrant of the square
    // (found from the image: the extent of non-background pixels along the middle row and column).
    let px = |x: u32, y: u32| {
        let k = ((y * size + x) * 4) as usize;
        [img.rgba[k], img.rgba[k + 1], img.rgba[k + 2]]
    };
    let bg = px(0, 0);
    let mid = size / 2;
    let cols: Vec<u32> = (0..size).filter(|&x| px(x, mid) != bg).collect();
    let rows: Vec<u32> = (0..size).filter(|&y| px(mid, y) != bg).collect();
    let (x0, x1) = (cols[0], *cols.last().unwrap());
    let (y0, y1) = (rows[0], *rows.last().unwrap());
    assert!(x1 - x0 > size / 3, "the square is drawn large: {x0}..{x1}");
    let at = |fx: f32, fy: f32| {
        px(
            x0 + ((x1 - x0) as f32 * fx) as u32,
            y0 + ((y1 - y0) as f32 * fy) as u32,
        )
    };
    // Ambient 1 and an sRGB texture drawn into an sRGB target: each texel's bytes come back
    // within one level (rounding of the decode and encode).
    for (q, (fx, fy)) in [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)]
        .into_iter()
        .enumerate()
    {
        let got = at(fx, fy);
        for (g, w) in got.iter().zip(QUADRANTS[q]) {
            assert!(
                g.abs_diff(w) <= 1,
                "quadrant {q}: got {got:?}, want {:?}",
                QUADRANTS[q]
            );
        }
    }

    // A heat map ignores the texture; an untextured triangle keeps its albedo (here skin).
    let mut heat = flat_view();
    heat.shading = Shading::Displacement { full_scale: 1.0 };
    let h = r.render(&gpu, Deform::Rest, &heat).unwrap();
    let k = ((mid * size + mid) * 4) as usize;
    let (hr, hg, hb) = (h.rgba[k], h.rgba[k + 1], h.rgba[k + 2]);
    // The cold end of the ramp, linear (0.05, 0.10, 0.60): sRGB about (63, 89, 203).
    assert!(hb > 180 && hr < 90 && hg < 110, "{:?}", (hr, hg, hb));
    let half = MeshTextures {
        triangles: vec![textures.triangles[0], None],
        ..textures.clone()
    };
    r.set_textures(&mut gpu, &half).unwrap();
    let img = r.render(&gpu, Deform::Rest, &flat_view()).unwrap();
    // Top right: the second triangle's, now untextured.
    let k = (((y0 + (y1 - y0) / 10) * size + x0 + (x1 - x0) * 9 / 10) * 4) as usize;
    let skin: Vec<u8> = mimic_render::SKIN_ALBEDO
        .iter()
        .map(|c| {
            (if *c <= 0.003_130_8 {
                c * 12.92
            } else {
                1.055 * c.powf(1.0 / 2.4) - 0.055
            } * 255.0)
                .round() as u8
        })
        .collect();
    for (g, w) in img.rgba[k..k + 3].iter().zip(&skin) {
        assert!(
            g.abs_diff(*w) <= 1,
            "untextured corner: {:?} vs skin {skin:?}",
            &img.rgba[k..k + 3]
        );
    }

    // Wrong sizes are refused.
    let short = MeshTextures {
        triangles: vec![None],
        ..textures.clone()
    };
    assert!(r.set_textures(&mut gpu, &short).is_err());
    let bad = MeshTextures {
        textures: Vec::new(),
        ..textures
    };
    let e = r.set_textures(&mut gpu, &bad).unwrap_err().to_string();
    assert_eq!(e, "triangle 0 uses texture 0, but there are 0");
}
