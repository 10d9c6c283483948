//! Grey texture maps combined into the images glTF's material reads. FBX's PBR materials
//! (3ds Max, Maya, Arnold) keep roughness, metalness and opacity as separate grey maps;
//! glTF reads roughness from the green and metalness from the blue channel of one image,
//! and opacity from the base colour's alpha. These are the only images kinegraph decodes
//! and encodes again (as PNG); every other image keeps its bytes as read.
//!
//! A map's value is its image's first channel (a grey image's only one, the red of a colour
//! one), as glTF reads occlusion; an opacity image with an alpha channel gives its alpha. Maps of different sizes are resampled (bilinear) to the
//! largest width and height among them. Values are copied as stored: these maps hold
//! linear data, not colours.

use std::io::Cursor;

use image::imageops::{self, FilterType};
use image::{GrayImage, ImageFormat, Rgb, RgbImage, RgbaImage};

use crate::model::Image;

/// One channel of a combined image: a grey map, or a constant where the material has no map.
#[derive(Clone, Copy, Debug)]
pub(super) enum Channel<'a> {
    /// The map's first channel; `invert` reads `1 − value` (a glossiness map as roughness).
    Map { image: &'a Image, invert: bool },
    /// A value in 0–1.
    Constant(f64),
}

/// The metallic-roughness image of a material: roughness in green, metalness in blue, red
/// (unused by glTF) white. At least one channel should be a map (its size is the image's).
pub(super) fn metallic_roughness(
    name: String,
    roughness: Channel<'_>,
    metalness: Channel<'_>,
) -> Result<Image, String> {
    let [roughness, metalness] = grey_planes([roughness, metalness])?;
    let (width, height) = roughness.dimensions();
    let packed = RgbImage::from_fn(width, height, |x, y| {
        Rgb([u8::MAX, roughness.get_pixel(x, y).0[0], metalness.get_pixel(x, y).0[0]])
    });
    encode_png(name, &image::DynamicImage::ImageRgb8(packed))
}

/// `base` (white where there is none) with `opacity` as its alpha, at the larger of the
/// two sizes: the opacity image's own alpha when it has one (a texture with transparency
/// connected as the opacity map, often the base colour image itself), else its first
/// channel (a grey map).
pub(super) fn with_opacity(name: String, base: Option<&Image>, opacity: &Image) -> Result<Image, String> {
    let decoded = decode(opacity)?;
    let mut opacity = plane(&decoded, if decoded.color().has_alpha() { 3 } else { 0 });
    let mut base = match base {
        Some(image) => decode(image)?.to_rgba8(),
        None => RgbaImage::from_pixel(opacity.width(), opacity.height(), image::Rgba([u8::MAX; 4])),
    };
    let width = base.width().max(opacity.width());
    let height = base.height().max(opacity.height());
    if base.dimensions() != (width, height) {
        base = imageops::resize(&base, width, height, FilterType::Triangle);
    }
    if opacity.dimensions() != (width, height) {
        opacity = imageops::resize(&opacity, width, height, FilterType::Triangle);
    }
    for (pixel, alpha) in base.pixels_mut().zip(opacity.pixels()) {
        pixel.0[3] = alpha.0[0];
    }
    encode_png(name, &image::DynamicImage::ImageRgba8(base))
}

/// The channels as grey planes of one size (the largest width and height among the maps).
fn grey_planes<const N: usize>(channels: [Channel<'_>; N]) -> Result<[GrayImage; N], String> {
    let mut maps = Vec::with_capacity(N);
    for channel in &channels {
        maps.push(match *channel {
            Channel::Map { image, invert } => {
                let mut plane = first_channel(image)?;
                if invert {
                    imageops::invert(&mut plane);
                }
                Some(plane)
            }
            Channel::Constant(_) => None,
        });
    }
    let width = maps.iter().flatten().map(GrayImage::width).max().unwrap_or(1);
    let height = maps.iter().flatten().map(GrayImage::height).max().unwrap_or(1);
    let planes: Vec<GrayImage> = maps
        .into_iter()
        .zip(channels)
        .map(|(map, channel)| match (map, channel) {
            (Some(plane), _) if plane.dimensions() == (width, height) => plane,
            (Some(plane), _) => imageops::resize(&plane, width, height, FilterType::Triangle),
            (None, Channel::Constant(v)) => GrayImage::from_pixel(width, height, image::Luma([unit_to_byte(v)])),
            (None, Channel::Map { .. }) => unreachable!("every map was decoded above"),
        })
        .collect();
    planes.try_into().map_err(|_| "channel count".to_owned())
}

/// An image's first channel.
fn first_channel(image: &Image) -> Result<GrayImage, String> {
    Ok(plane(&decode(image)?, 0))
}

/// Channel `channel` (0-3: red, green, blue, alpha) of a decoded image.
fn plane(decoded: &image::DynamicImage, channel: usize) -> GrayImage {
    let rgba = decoded.to_rgba8();
    GrayImage::from_fn(rgba.width(), rgba.height(), |x, y| image::Luma([rgba.get_pixel(x, y).0[channel]]))
}

fn decode(image: &Image) -> Result<image::DynamicImage, String> {
    image::load_from_memory(&image.bytes)
        .map_err(|e| format!("image '{}' cannot be decoded: {e}", image.name.as_deref().unwrap_or("unnamed")))
}

/// 0–1 as a byte, rounded (values outside clamp).
fn unit_to_byte(v: f64) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0).round() as u8
}

fn encode_png(name: String, image: &image::DynamicImage) -> Result<Image, String> {
    let mut bytes = Cursor::new(Vec::new());
    image.write_to(&mut bytes, ImageFormat::Png).map_err(|e| format!("PNG encoding failed: {e}"))?;
    Ok(Image { name: Some(name), mime_type: "image/png".to_owned(), bytes: bytes.into_inner() })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn png(image: image::DynamicImage) -> Image {
        encode_png("test.png".into(), &image).unwrap()
    }

    /// A grey PNG whose pixel (x, y) is `f(x, y)`.
    fn grey(width: u32, height: u32, f: impl Fn(u32, u32) -> u8) -> Image {
        png(image::DynamicImage::ImageLuma8(GrayImage::from_fn(width, height, |x, y| image::Luma([f(x, y)]))))
    }

    fn decoded(image: &Image) -> RgbaImage {
        image::load_from_memory(&image.bytes).unwrap().to_rgba8()
    }

    /// Roughness lands in green and metalness in blue, pixel for pixel; a glossiness map is
    /// inverted; a constant fills its channel (0.5 → 128); red stays white.
    #[test]
    fn maps_and_constants_pack_into_green_and_blue() {
        let rough = grey(4, 3, |x, y| (10 * x + 50 * y) as u8);
        let metal = grey(4, 3, |x, y| (200 - 7 * x - 30 * y) as u8);
        let packed = metallic_roughness(
            "m".into(),
            Channel::Map { image: &rough, invert: false },
            Channel::Map { image: &metal, invert: false },
        )
        .unwrap();
        assert_eq!(packed.mime_type, "image/png");
        for (x, y, p) in decoded(&packed).enumerate_pixels() {
            assert_eq!(p.0, [255, (10 * x + 50 * y) as u8, (200 - 7 * x - 30 * y) as u8, 255], "({x}, {y})");
        }
        let packed =
            metallic_roughness("m".into(), Channel::Map { image: &rough, invert: true }, Channel::Constant(0.5))
                .unwrap();
        for (x, y, p) in decoded(&packed).enumerate_pixels() {
            assert_eq!(p.0, [255, 255 - (10 * x + 50 * y) as u8, 128, 255], "({x}, {y})");
        }
    }

    /// A smaller map is stretched over the larger one's size: a uniform map stays uniform,
    /// and a map's colour image gives its red channel.
    #[test]
    fn maps_of_different_sizes_meet_at_the_largest() {
        let rough = grey(8, 2, |_, _| 77);
        let metal = png(image::DynamicImage::ImageRgb8(RgbImage::from_pixel(3, 5, Rgb([40, 90, 250]))));
        let packed = metallic_roughness(
            "m".into(),
            Channel::Map { image: &rough, invert: false },
            Channel::Map { image: &metal, invert: false },
        )
        .unwrap();
        let image = decoded(&packed);
        assert_eq!(image.dimensions(), (8, 5));
        assert!(image.pixels().all(|p| p.0 == [255, 77, 40, 255]));
    }

    /// Opacity becomes the base colour's alpha with the colour untouched; without a base
    /// image the colour is white (the material's factor gives it); an opacity image with
    /// an alpha channel gives its alpha.
    #[test]
    fn opacity_becomes_the_alpha_of_the_base_colour() {
        let base = png(image::DynamicImage::ImageRgb8(RgbImage::from_fn(3, 2, |x, y| Rgb([x as u8, y as u8, 9]))));
        let opacity = grey(3, 2, |x, y| (100 + x + 10 * y) as u8);
        for (x, y, p) in decoded(&with_opacity("b".into(), Some(&base), &opacity).unwrap()).enumerate_pixels() {
            assert_eq!(p.0, [x as u8, y as u8, 9, (100 + x + 10 * y) as u8]);
        }
        for (x, y, p) in decoded(&with_opacity("b".into(), None, &opacity).unwrap()).enumerate_pixels() {
            assert_eq!(p.0, [255, 255, 255, (100 + x + 10 * y) as u8]);
        }
        // An opacity texture with an alpha channel gives its alpha, not its red.
        let see_through = png(image::DynamicImage::ImageRgba8(RgbaImage::from_fn(3, 2, |x, y| {
            image::Rgba([200, 10, 10, (40 * x + 7 * y) as u8])
        })));
        for (x, y, p) in decoded(&with_opacity("b".into(), Some(&base), &see_through).unwrap()).enumerate_pixels() {
            assert_eq!(p.0, [x as u8, y as u8, 9, (40 * x + 7 * y) as u8]);
        }
        let broken =
            Image { name: Some("broken.png".into()), mime_type: "image/png".into(), bytes: b"\x89PNG".to_vec() };
        let err = with_opacity("b".into(), None, &broken).unwrap_err();
        assert!(err.starts_with("image 'broken.png' cannot be decoded"), "{err}");
    }
}
