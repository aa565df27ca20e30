//! Decoding one 1280x720 camera buffer to packed RGB24, per pixel format, with the runtime's
//! decoders (`mgmot::camera::decode`), and the `image` crate's JPEG path for comparison.
//!
//! The picture is synthetic: a sea-like gradient with fine pseudo-random texture (noise costs
//! a JPEG decoder more than flat areas), JPEG-encoded at quality 85 as webcams do; YUYV and
//! NV12 cost the same whatever the pixel values.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use mgmot::camera::decode::{decode_to_rgb, FrameLayout, PixelFormat};
use std::hint::black_box;

const W: u32 = 1280;
const H: u32 = 720;

fn picture() -> Vec<u8> {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut noise = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state % 24) as i32 - 12
    };
    let mut rgb = Vec::with_capacity((W * H * 3) as usize);
    for y in 0..H {
        for x in 0..W {
            let base = [
                20 + (40 * y / H) as i32,
                60 + (60 * y / H) as i32 + (20 * x / W) as i32,
                90 + (80 * y / H) as i32,
            ];
            for c in base {
                rgb.push((c + noise()).clamp(0, 255) as u8);
            }
        }
    }
    rgb
}

fn bench(c: &mut Criterion) {
    let rgb = picture();
    let mut mjpg = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut mjpg, 85)
        .encode(&rgb, W, H, image::ExtendedColorType::Rgb8)
        .expect("encoding the test JPEG");
    // YUV content: arbitrary but valid bytes (the converters are data-independent).
    let yuyv: Vec<u8> = (0..W * H * 2).map(|i| (16 + i % 220) as u8).collect();
    let nv12: Vec<u8> = (0..W * H * 3 / 2).map(|i| (16 + i % 220) as u8).collect();

    let mut group = c.benchmark_group("camera_decode_1280x720");
    group.throughput(Throughput::Elements(1));
    let mut out = Vec::new();
    for (format, data) in [
        (PixelFormat::Mjpg, &mjpg),
        (PixelFormat::Yuyv, &yuyv),
        (PixelFormat::Nv12, &nv12),
    ] {
        let layout = FrameLayout::packed(format, W, H);
        group.bench_with_input(
            BenchmarkId::new("mgmot", format.to_string()),
            data,
            |b, data| {
                b.iter(|| {
                    decode_to_rgb(&layout, black_box(data), &mut out).expect("decodes");
                    black_box(&out);
                })
            },
        );
    }
    group.bench_with_input(BenchmarkId::new("image-crate", "MJPG"), &mjpg, |b, data| {
        b.iter(|| {
            let img =
                image::load_from_memory_with_format(black_box(data), image::ImageFormat::Jpeg)
                    .expect("decodes")
                    .into_rgb8();
            black_box(img);
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
