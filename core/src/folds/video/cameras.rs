//! The calibrated cameras of a capture and their images (docs/folds.md): parsing and validating `cameras.json`,
//! locating `images/<camera>/frame_NNNN.png`, and loading an image with its garment mask.
//!
//! Popa et al. 2009 §5.1 project the fold edges "using the available camera calibration"; a wrong calibration
//! silently puts folds in the wrong place, so the file is checked strictly: positive focal lengths, proper
//! rotations (orthonormal, determinant +1), a `center` (if given) that agrees with `-Rᵀ t`, unique names.

use crate::error::{Error, Result};
use crate::render::CalibratedCamera;
use crate::vec3::{self, M3, V3};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The image file pattern used when `cameras.json` names none: `%s` is the camera name, `%04d` the frame
/// number, relative to the images directory.
pub const DEFAULT_IMAGE_PATTERN: &str = "%s/frame_%04d.png";

#[derive(Debug, Clone, Serialize, Deserialize)]
struct CameraJson {
    name: String,
    width: u32,
    height: u32,
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    #[serde(rename = "R")]
    r: M3,
    t: V3,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    center: Option<V3>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
struct RigJson {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    convention: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    image_pattern: Option<String>,
    cameras: Vec<CameraJson>,
}

/// One named camera.
#[derive(Debug, Clone)]
pub struct NamedCamera {
    pub name: String,
    pub camera: CalibratedCamera,
}

/// The cameras of a capture and where their images are.
#[derive(Debug, Clone)]
pub struct CameraRig {
    pub cameras: Vec<NamedCamera>,
    /// Directory the image pattern is relative to.
    pub images_dir: PathBuf,
    /// Pattern of an image path below `images_dir`: `%s` = camera name, `%d` / `%0Nd` = frame number.
    pub image_pattern: String,
}

/// A loaded camera image: linear-ish grey (0–255, Rec. 601 luma of the sRGB values), colour for the hue test,
/// and the garment mask (alpha ≥ 0.5, or everything for images without alpha).
#[derive(Debug, Clone)]
pub struct Photo {
    pub width: u32,
    pub height: u32,
    pub gray: Vec<f32>,
    pub rgb: Vec<[f32; 3]>,
    pub mask: Vec<bool>,
    pub has_alpha: bool,
}

impl Photo {
    /// A photo from an RGBA image (alpha < 128 is background).
    pub fn from_rgba(img: &image::RgbaImage) -> Photo {
        let (w, h) = img.dimensions();
        let n = (w * h) as usize;
        let mut gray = Vec::with_capacity(n);
        let mut rgb = Vec::with_capacity(n);
        let mut mask = Vec::with_capacity(n);
        let mut has_alpha = false;
        for p in img.pixels() {
            let [r, g, b, a] = p.0.map(|c| c as f32);
            gray.push(0.299 * r + 0.587 * g + 0.114 * b);
            rgb.push([r, g, b]);
            mask.push(a >= 128.0);
            has_alpha |= a < 255.0;
        }
        Photo {
            width: w,
            height: h,
            gray,
            rgb,
            mask,
            has_alpha,
        }
    }

    /// Bilinear sample of the grey image at pixel-centre coordinates (clamped at the border).
    pub fn gray_at(&self, p: [f64; 2]) -> f32 {
        bilinear(&self.gray, self.width, self.height, p)
    }

    /// Bilinear sample of the colour image.
    pub fn rgb_at(&self, p: [f64; 2]) -> [f32; 3] {
        let (x0, y0, fx, fy) = cell(self.width, self.height, p);
        let w = self.width as usize;
        let idx = |x: usize, y: usize| y * w + x;
        let x1 = (x0 + 1).min(self.width as usize - 1);
        let y1 = (y0 + 1).min(self.height as usize - 1);
        let c = [
            self.rgb[idx(x0, y0)],
            self.rgb[idx(x1, y0)],
            self.rgb[idx(x0, y1)],
            self.rgb[idx(x1, y1)],
        ];
        [0, 1, 2].map(|k| {
            (c[0][k] * (1.0 - fx) + c[1][k] * fx) * (1.0 - fy)
                + (c[2][k] * (1.0 - fx) + c[3][k] * fx) * fy
        })
    }

    /// Whether the nearest pixel to `p` is garment.
    pub fn on_mask(&self, p: [f64; 2]) -> bool {
        let x = p[0].round();
        let y = p[1].round();
        if !(x >= 0.0 && y >= 0.0 && x < self.width as f64 && y < self.height as f64) {
            return false;
        }
        self.mask[y as usize * self.width as usize + x as usize]
    }

    /// The mask shrunk by `margin` pixels (Chebyshev distance), so edge pixels next to the silhouette can be
    /// told apart from fold edges inside the garment.
    pub fn eroded_mask(&self, margin: f64) -> Vec<bool> {
        let steps = margin.ceil().max(0.0) as usize;
        let (w, h) = (self.width as usize, self.height as usize);
        let mut m = self.mask.clone();
        if w == 0 || h == 0 {
            return m;
        }
        let mut rows = vec![false; m.len()];
        for _ in 0..steps {
            // One step keeps a pixel whose 3x3 neighbourhood (the part inside the image) is all garment: the
            // minimum along rows, then along columns; a clamped index repeats a pixel already in the window.
            for (o, r) in rows.chunks_exact_mut(w).zip(m.chunks_exact(w)) {
                for x in 0..w {
                    o[x] = r[x.saturating_sub(1)] & r[x] & r[(x + 1).min(w - 1)];
                }
            }
            for y in 0..h {
                let (up, down) = (y.saturating_sub(1) * w, (y + 1).min(h - 1) * w);
                for x in 0..w {
                    m[y * w + x] = rows[up + x] & rows[y * w + x] & rows[down + x];
                }
            }
        }
        m
    }
}

fn cell(w: u32, h: u32, p: [f64; 2]) -> (usize, usize, f32, f32) {
    let x = p[0].clamp(0.0, (w - 1) as f64);
    let y = p[1].clamp(0.0, (h - 1) as f64);
    let x = if x.is_nan() { 0.0 } else { x };
    let y = if y.is_nan() { 0.0 } else { y };
    let x0 = x.floor() as usize;
    let y0 = y.floor() as usize;
    (x0, y0, (x - x0 as f64) as f32, (y - y0 as f64) as f32)
}

/// Bilinear sample of a row-major `w x h` grid at `p` (pixel centres at integers), clamped at the border.
pub fn bilinear(data: &[f32], w: u32, h: u32, p: [f64; 2]) -> f32 {
    let (x0, y0, fx, fy) = cell(w, h, p);
    let wu = w as usize;
    let x1 = (x0 + 1).min(wu - 1);
    let y1 = (y0 + 1).min(h as usize - 1);
    let a = data[y0 * wu + x0];
    let b = data[y0 * wu + x1];
    let c = data[y1 * wu + x0];
    let d = data[y1 * wu + x1];
    (a * (1.0 - fx) + b * fx) * (1.0 - fy) + (c * (1.0 - fx) + d * fx) * fy
}

/// Widest `%0Nd` an image pattern may use.
pub const MAX_PATTERN_WIDTH: usize = 64;

/// Formats a printf-style image pattern: `%s` → camera name, `%d` / `%0Nd` / `%Nd` → frame number, `%%` → `%`.
pub fn format_pattern(
    pattern: &str,
    camera: &str,
    number: u64,
) -> std::result::Result<String, String> {
    let mut out = String::new();
    let mut chars = pattern.chars().peekable();
    while let Some(c) = chars.next() {
        if c != '%' {
            out.push(c);
            continue;
        }
        let mut spec = String::new();
        while let Some(&d) = chars.peek() {
            if d.is_ascii_digit() {
                spec.push(d);
                chars.next();
            } else {
                break;
            }
        }
        match chars.next() {
            Some('s') if spec.is_empty() => out.push_str(camera),
            Some('d') => {
                let zero = spec.starts_with('0');
                // A frame number has at most 20 digits; the formatter panics on widths above 65535 and a huge
                // width would allocate that much per path anyway.
                let width = match spec.parse::<usize>() {
                    _ if spec.is_empty() => 0,
                    Ok(w) if w <= MAX_PATTERN_WIDTH => w,
                    _ => {
                        return Err(format!(
                            "the width of `%{spec}d` is too large (at most {MAX_PATTERN_WIDTH})"
                        ))
                    }
                };
                if zero {
                    out.push_str(&format!("{number:0width$}"));
                } else {
                    out.push_str(&format!("{number:width$}"));
                }
            }
            Some('%') if spec.is_empty() => out.push('%'),
            other => {
                return Err(format!(
                "unsupported conversion `%{spec}{}` (use %s for the camera and %04d for the frame)",
                other.map(String::from).unwrap_or_default()
            ))
            }
        }
    }
    Ok(out)
}

impl CameraRig {
    /// Reads `cameras.json`. `images_dir` overrides where images are looked for; by default the pattern in the
    /// file (e.g. `images/%s/frame_%04d.png`) is taken relative to the file's directory.
    pub fn read(path: &Path, images_dir: Option<&Path>) -> Result<CameraRig> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Self::parse(&text, path, images_dir)
    }

    /// Parses and validates camera JSON; `path` labels errors and anchors relative image patterns.
    pub fn parse(text: &str, path: &Path, images_dir: Option<&Path>) -> Result<CameraRig> {
        let err = |msg: String| Error::format(path, None, msg);
        let rig: RigJson = match serde_json::from_str::<RigJson>(text) {
            Ok(r) => r,
            Err(e) => match serde_json::from_str::<Vec<CameraJson>>(text) {
                Ok(cameras) => RigJson {
                    convention: None,
                    image_pattern: None,
                    cameras,
                },
                Err(_) => return Err(err(format!("line {} column {}: {e}", e.line(), e.column()))),
            },
        };
        if rig.cameras.is_empty() {
            return Err(err("no cameras".into()));
        }
        let mut cameras = Vec::with_capacity(rig.cameras.len());
        for (i, c) in rig.cameras.iter().enumerate() {
            let label = format!("camera {i} (`{}`)", c.name);
            if c.name.is_empty() || c.name.contains(['/', '\\']) {
                return Err(err(format!(
                    "{label}: the name must be non-empty and contain no path separators"
                )));
            }
            if cameras.iter().any(|o: &NamedCamera| o.name == c.name) {
                return Err(err(format!("{label}: the name is used twice")));
            }
            if c.width == 0 || c.height == 0 {
                return Err(err(format!(
                    "{label}: image size {}x{} is empty",
                    c.width, c.height
                )));
            }
            if !(c.fx.is_finite() && c.fx > 0.0 && c.fy.is_finite() && c.fy > 0.0) {
                return Err(err(format!(
                    "{label}: focal lengths must be positive (fx {}, fy {})",
                    c.fx, c.fy
                )));
            }
            if !(c.cx.is_finite() && c.cy.is_finite() && vec3::is_finite(c.t)) {
                return Err(err(format!("{label}: cx, cy and t must be finite")));
            }
            check_rotation(&c.r).map_err(|m| err(format!("{label}: R {m}")))?;
            let camera = CalibratedCamera {
                fx: c.fx,
                fy: c.fy,
                cx: c.cx,
                cy: c.cy,
                r: c.r,
                t: c.t,
                width: c.width,
                height: c.height,
            };
            if let Some(center) = c.center {
                let got = camera.center();
                let d = vec3::norm(vec3::sub(center, got));
                if d.is_nan() || d > 1e-4 * (1.0 + vec3::norm(got)) {
                    return Err(err(format!(
                        "{label}: `center` {center:?} disagrees with -Rᵀt = {got:?} (R, t must map world to camera)"
                    )));
                }
            }
            cameras.push(NamedCamera {
                name: c.name.clone(),
                camera,
            });
        }
        let base = path
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        let (images_dir, image_pattern) = match (&rig.image_pattern, images_dir) {
            // `--images DIR` replaces everything up to the camera directory of the file's pattern.
            (Some(p), Some(dir)) => (
                dir.to_path_buf(),
                p.find("%s").map_or(p.clone(), |k| p[k..].to_string()),
            ),
            (Some(p), None) => (base.to_path_buf(), p.clone()),
            (None, Some(dir)) => (dir.to_path_buf(), DEFAULT_IMAGE_PATTERN.to_string()),
            (None, None) => (base.join("images"), DEFAULT_IMAGE_PATTERN.to_string()),
        };
        format_pattern(&image_pattern, "c", 1).map_err(|m| err(format!("image_pattern: {m}")))?;
        Ok(CameraRig {
            cameras,
            images_dir,
            image_pattern,
        })
    }

    /// Path of the image of camera `cam` for image frame `number`.
    pub fn image_path(&self, cam: usize, number: u64) -> PathBuf {
        let rel = format_pattern(&self.image_pattern, &self.cameras[cam].name, number)
            .unwrap_or_else(|_| self.image_pattern.clone());
        self.images_dir.join(rel)
    }

    /// Checks that every camera has an image of its stated size for each image number; errors name the camera,
    /// the frame and the file. Reads only PNG headers.
    pub fn check_images(&self, frames: &[(usize, u64)]) -> Result<()> {
        for (c, nc) in self.cameras.iter().enumerate() {
            for &(t, number) in frames {
                let path = self.image_path(c, number);
                let (w, h) = image::image_dimensions(&path).map_err(|e| {
                    Error::format(
                        &path,
                        None,
                        format!("camera {}, frame {t}: cannot read the image: {e}", nc.name),
                    )
                })?;
                self.check_size(c, t, &path, w, h)?;
            }
        }
        Ok(())
    }

    fn check_size(&self, cam: usize, t: usize, path: &Path, w: u32, h: u32) -> Result<()> {
        let c = &self.cameras[cam];
        if (w, h) != (c.camera.width, c.camera.height) {
            return Err(Error::format(
                path,
                None,
                format!(
                    "camera {}, frame {t}: the image is {w}x{h} but cameras.json says {}x{}",
                    c.name, c.camera.width, c.camera.height
                ),
            ));
        }
        Ok(())
    }

    /// Loads the image of camera `cam` for sequence frame `t` (image number `number`).
    pub fn load(&self, cam: usize, t: usize, number: u64) -> Result<Photo> {
        let path = self.image_path(cam, number);
        let name = &self.cameras[cam].name;
        let img = image::ImageReader::open(&path)
            .map_err(|e| {
                Error::format(
                    &path,
                    None,
                    format!("camera {name}, frame {t}: cannot open the image: {e}"),
                )
            })?
            .with_guessed_format()
            .map_err(|e| Error::io(&path, e))?
            .decode()
            .map_err(|e| {
                Error::format(
                    &path,
                    None,
                    format!("camera {name}, frame {t}: cannot decode the image: {e}"),
                )
            })?;
        self.check_size(cam, t, &path, img.width(), img.height())?;
        Ok(Photo::from_rgba(&img.to_rgba8()))
    }

    /// Serialises the rig (used by the synthetic video writer).
    pub fn to_json(&self) -> String {
        let rig = RigJson {
            convention: Some(
                "OpenCV pinhole: X_cam = R X_world + t; x right, y down, z forward; pixel (0,0) is the centre of \
                 the top-left pixel; no distortion"
                    .into(),
            ),
            image_pattern: Some(format!("images/{}", self.image_pattern)),
            cameras: self
                .cameras
                .iter()
                .map(|c| CameraJson {
                    name: c.name.clone(),
                    width: c.camera.width,
                    height: c.camera.height,
                    fx: c.camera.fx,
                    fy: c.camera.fy,
                    cx: c.camera.cx,
                    cy: c.camera.cy,
                    r: c.camera.r,
                    t: c.camera.t,
                    center: Some(c.camera.center()),
                })
                .collect(),
        };
        serde_json::to_string_pretty(&rig).expect("cameras serialise")
    }
}

/// `Ok` when `r` is a proper rotation: orthonormal rows within 1e-4 and determinant +1 (not a reflection).
fn check_rotation(r: &M3) -> std::result::Result<(), String> {
    if !r.iter().all(|row| vec3::is_finite(*row)) {
        return Err("has non-finite entries".into());
    }
    let rrt = vec3::mat_mul(r, &vec3::transpose(r));
    for (i, row) in rrt.iter().enumerate() {
        for (j, v) in row.iter().enumerate() {
            let want = if i == j { 1.0 } else { 0.0 };
            if (v - want).abs() > 1e-4 {
                return Err(format!("is not orthonormal (R Rᵀ[{i}][{j}] = {v:.6})"));
            }
        }
    }
    let det = vec3::dot(r[0], vec3::cross(r[1], r[2]));
    if det < 0.0 {
        return Err(format!(
            "is a reflection (determinant {det:.4}), not a rotation"
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const ONE: &str = r#"{"image_pattern": "images/%s/frame_%04d.png", "cameras": [
        {"name": "a", "width": 64, "height": 48, "fx": 50, "fy": 50, "cx": 31.5, "cy": 23.5,
         "R": [[1,0,0],[0,1,0],[0,0,1]], "t": [0,0,2], "center": [0,0,-2]}]}"#;

    #[test]
    fn parses_and_locates_images() {
        let rig = CameraRig::parse(ONE, Path::new("/x/cameras.json"), None).unwrap();
        assert_eq!(
            rig.image_path(0, 7),
            Path::new("/x/images/a/frame_0007.png")
        );
        let rig =
            CameraRig::parse(ONE, Path::new("/x/cameras.json"), Some(Path::new("/y"))).unwrap();
        assert_eq!(rig.image_path(0, 12), Path::new("/y/a/frame_0012.png"));
        assert_eq!(format_pattern("%s_%d_%3d%%", "c", 5).unwrap(), "c_5_  5%");
        assert!(format_pattern("%x", "c", 5).is_err());
        // Round trip through to_json.
        let back = CameraRig::parse(&rig.to_json(), Path::new("/z/c.json"), None).unwrap();
        assert_eq!(back.cameras[0].camera, rig.cameras[0].camera);
        assert_eq!(
            back.image_path(0, 3),
            Path::new("/z/images/a/frame_0003.png")
        );
    }

    /// Fuzzing found `%999999999d` in `image_pattern`: the formatter panicked ("Formatting argument out of
    /// range") when the pattern was checked, instead of the file being rejected.
    #[test]
    fn huge_pattern_widths_are_an_error_not_a_panic() {
        for pattern in [
            "%999999999d",
            "%0100000d",
            "%99999999999999999999999d",
            "%65d",
        ] {
            let text = ONE.replace("images/%s/frame_%04d.png", pattern);
            let e = CameraRig::parse(&text, Path::new("c.json"), None)
                .unwrap_err()
                .to_string();
            assert!(
                e.contains("c.json") && e.contains("image_pattern") && e.contains("too large"),
                "{pattern}: {e}"
            );
        }
        assert_eq!(format_pattern("%064d", "c", 7).unwrap().len(), 64);
    }

    #[test]
    fn rejects_bad_calibrations_naming_the_camera() {
        let cases = [
            (
                ONE.replace("\"fx\": 50", "\"fx\": -50"),
                "focal lengths must be positive",
            ),
            (
                ONE.replace("[0,1,0],[0,0,1]", "[0,0,1],[0,1,0]"),
                "reflection",
            ),
            (
                ONE.replace("[1,0,0],[0,1,0]", "[1,0,0],[0,2,0]"),
                "not orthonormal",
            ),
            (ONE.replace("[0,0,-2]", "[0,0,2]"), "disagrees"),
            (ONE.replace("\"width\": 64", "\"width\": 0"), "empty"),
            (ONE.replace("\"name\": \"a\"", "\"name\": \"\""), "name"),
            ("{\"cameras\": []}".to_string(), "no cameras"),
            ("{\"cameras\": [".to_string(), "line 1"),
        ];
        for (text, want) in cases {
            let e = CameraRig::parse(&text, Path::new("c.json"), None)
                .unwrap_err()
                .to_string();
            assert!(e.contains(want) && e.contains("c.json"), "{want}: {e}");
        }
    }

    #[test]
    fn eroded_mask_equals_step_by_step_neighbourhood_erosion() {
        // Reference: per step, a pixel stays garment when every pixel of its 3x3 neighbourhood inside the image is.
        let reference = |mask: &[bool], w: usize, h: usize, steps: usize| {
            let mut m = mask.to_vec();
            for _ in 0..steps {
                let prev = m.clone();
                for y in 0..h {
                    for x in 0..w {
                        let mut keep = prev[y * w + x];
                        for yy in y.saturating_sub(1)..=(y + 1).min(h - 1) {
                            for xx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
                                keep &= prev[yy * w + xx];
                            }
                        }
                        m[y * w + x] = keep;
                    }
                }
            }
            m
        };
        let mut s = 3u64;
        for &(w, h) in &[(37usize, 23usize), (1, 9), (8, 1), (1, 1)] {
            // A blob with holes and specks, touching the border.
            let mask: Vec<bool> = (0..w * h)
                .map(|i| {
                    s = s
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    let (x, y) = ((i % w) as f64, (i / w) as f64);
                    let inside = (x - 0.6 * w as f64).powi(2) + (y - 0.4 * h as f64).powi(2)
                        < (0.45 * w.max(h) as f64).powi(2);
                    inside != (s >> 40).is_multiple_of(13)
                })
                .collect();
            let photo = Photo {
                width: w as u32,
                height: h as u32,
                gray: vec![0.0; w * h],
                rgb: vec![[0.0; 3]; w * h],
                mask: mask.clone(),
                has_alpha: true,
            };
            for margin in [0.0, 1.0, 2.5, 3.0] {
                let steps = f64::ceil(margin) as usize;
                assert_eq!(
                    photo.eroded_mask(margin),
                    reference(&mask, w, h, steps),
                    "{w}x{h} margin {margin}"
                );
            }
        }
    }

    #[test]
    fn missing_and_wrongly_sized_images_name_camera_and_frame() {
        let dir = tempfile::tempdir().unwrap();
        let rig = CameraRig::parse(ONE, &dir.path().join("cameras.json"), None).unwrap();
        let e = rig.check_images(&[(0, 1)]).unwrap_err().to_string();
        assert!(
            e.contains("camera a, frame 0") && e.contains("frame_0001.png"),
            "{e}"
        );
        std::fs::create_dir_all(dir.path().join("images/a")).unwrap();
        crate::render::save_png(
            &image::RgbImage::new(10, 10),
            &dir.path().join("images/a/frame_0002.png"),
        )
        .unwrap();
        let e = rig.check_images(&[(1, 2)]).unwrap_err().to_string();
        assert!(
            e.contains("camera a, frame 1") && e.contains("10x10") && e.contains("64x48"),
            "{e}"
        );
        let e = rig.load(0, 1, 2).unwrap_err().to_string();
        assert!(e.contains("camera a, frame 1"), "{e}");
    }
}
