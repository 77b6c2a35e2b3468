//! The screenshot feature's decisions, away from Vulkan and the file system: where the runtime
//! folder's trigger, instance and result files are, when the trigger is looked at again, which
//! folder the pictures go to (`screenshot.dir`, else the XDG pictures folder), what a picture is
//! called, which part of a swapchain image is copied, and how its texels become PNG samples.
#![forbid(unsafe_code)]

use crate::core::views::ImageRect;
use std::path::{Path, PathBuf};

/// How often at most the trigger files are looked at (one `stat` or `open` each): a person
/// asking for a screenshot cannot tell 100 ms apart, the app's frame loop never pays more.
pub const TRIGGER_INTERVAL_NS: u64 = 100_000_000;

/// Whether the trigger is due for a look at `now_ns` after the last look at `last_ns`.
pub fn trigger_due(last_ns: Option<u64>, now_ns: u64) -> bool {
    last_ns.is_none_or(|last| now_ns.saturating_sub(last) >= TRIGGER_INTERVAL_NS)
}

/// A file whose modification is the trigger (`screenshot.trigger`): the first look only notes its
/// state (a file left from an earlier session must not fire), every later change of its
/// modification time (a new file included) fires once.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TouchWatch {
    /// (looked at least once, modification time in ns since the epoch when the file existed).
    seen: Option<Option<u128>>,
}

impl TouchWatch {
    /// Notes the file's modification time now (None: no such file); true when it is a new touch.
    pub fn fired(&mut self, mtime_ns: Option<u128>) -> bool {
        let before = self.seen.replace(mtime_ns);
        match (before, mtime_ns) {
            (Some(old), Some(new)) => old != Some(new),
            _ => false,
        }
    }
}

/// The folder the layer and `stereoshim screenshot` meet in: `<private base>/stereoshim/screenshot`
/// (`$XDG_RUNTIME_DIR` first, as for the generated Vulkan manifest: `crate::manifests::private_fs`).
pub fn runtime_folder(env: &dyn Fn(&str) -> Option<String>) -> Option<PathBuf> {
    crate::manifests::private_fs::private_base(env).map(|b| b.join("stereoshim").join("screenshot"))
}

/// `<pid>.json`: a running instance (its app name), written by the layer while a session runs.
pub fn instance_file(folder: &Path, pid: u32) -> PathBuf {
    folder.join(format!("{pid}.json"))
}

/// `<pid>.trigger`: written by `stereoshim screenshot` (its content a request number), removed by
/// the layer when it takes the screenshot.
pub fn trigger_file(folder: &Path, pid: u32) -> PathBuf {
    folder.join(format!("{pid}.trigger"))
}

/// `<pid>.done.json`: what the layer wrote for the latest request (files or error).
pub fn done_file(folder: &Path, pid: u32) -> PathBuf {
    folder.join(format!("{pid}.done.json"))
}

/// The pid of an instance file's name (`1234.json`).
pub fn instance_pid(file_name: &str) -> Option<u32> {
    // The same naming as the live folder's announcements.
    crate::core::live::announced_pid(file_name)
}

/// A trigger file's request number (0 when it has none: a plain `touch`).
pub fn request_number(text: &str) -> u64 {
    text.trim().parse().unwrap_or(0)
}

/// `XDG_PICTURES_DIR` of a `user-dirs.dirs` file as xdg-user-dirs writes it
/// (`XDG_PICTURES_DIR="$HOME/Pictures"`; only `$HOME/…` or absolute paths are allowed there).
pub fn pictures_from_user_dirs(text: &str, home: Option<&Path>) -> Option<PathBuf> {
    let line = text.lines().map(str::trim).find(|l| l.starts_with("XDG_PICTURES_DIR="))?;
    let value = line["XDG_PICTURES_DIR=".len()..].trim().trim_matches('"');
    if let Some(rest) = value.strip_prefix("$HOME") {
        let rest = rest.trim_start_matches('/');
        return home.map(|h| if rest.is_empty() { h.to_path_buf() } else { h.join(rest) });
    }
    let p = PathBuf::from(value);
    p.is_absolute().then_some(p)
}

/// Where pictures go: `screenshot.dir` when set, else `<pictures>/stereoshim` with pictures from
/// `$XDG_PICTURES_DIR`, else `$XDG_CONFIG_HOME/user-dirs.dirs` (`user_dirs`: its text), else
/// `~/Pictures`. None when nothing is known (no HOME).
pub fn output_folder(configured: &str, env: &dyn Fn(&str) -> Option<String>, user_dirs: Option<&str>) -> Option<PathBuf> {
    if !configured.trim().is_empty() {
        return Some(PathBuf::from(configured.trim()));
    }
    let home = env("HOME").map(PathBuf::from).filter(|p| p.is_absolute());
    let pictures = env("XDG_PICTURES_DIR")
        .map(PathBuf::from)
        .filter(|p| p.is_absolute())
        .or_else(|| user_dirs.and_then(|t| pictures_from_user_dirs(t, home.as_deref())))
        .or_else(|| home.map(|h| h.join("Pictures")))?;
    Some(pictures.join("stereoshim"))
}

/// Where `user-dirs.dirs` is: `$XDG_CONFIG_HOME`, else `~/.config`.
pub fn user_dirs_file(env: &dyn Fn(&str) -> Option<String>) -> Option<PathBuf> {
    let abs = |k: &str| env(k).map(PathBuf::from).filter(|p| p.is_absolute());
    abs("XDG_CONFIG_HOME").or_else(|| abs("HOME").map(|h| h.join(".config"))).map(|c| c.join("user-dirs.dirs"))
}

/// The app's name as a file name part: letters, digits, `.`, `_` and `-` kept, the rest `_`.
pub fn app_part(app: &str) -> String {
    let s: String = app.trim().chars().map(|c| if c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-') { c } else { '_' }).collect();
    let s = s.trim_start_matches('.').to_string();
    if s.is_empty() {
        "app".into()
    } else {
        s
    }
}

/// UTC date and time of `unix_ms` as `YYYYMMDD-HHMMSS-mmm` (sortable, no time zone needed).
pub fn date_time(unix_ms: u64) -> String {
    let (secs, ms) = (unix_ms / 1000, unix_ms % 1000);
    let (days, rem) = (secs / 86_400, secs % 86_400);
    // Days since 1970-01-01 to a civil date (Howard Hinnant's algorithm).
    let z = days as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!("{y:04}{m:02}{d:02}-{:02}{:02}{:02}-{ms:03}", rem / 3600, rem / 60 % 60, rem % 60)
}

/// `<app>-<date-time>`: the pictures' common name, `-view-<i>.png` and `.json` appended.
pub fn file_stem(app: &str, unix_ms: u64) -> String {
    format!("{}-{}", app_part(app), date_time(unix_ms))
}

pub fn view_file(stem: &str, view: u32) -> String {
    format!("{stem}-view-{view}.png")
}

/// The PNG of view `view` as the display got it from the upscale (`upscale.enabled`).
pub fn display_file(stem: &str, view: u32) -> String {
    format!("{stem}-view-{view}-display.png")
}

/// The part of a `width` × `height` image an `imageRect` names, clipped to the image: (x, y,
/// width, height); None when nothing of it is inside.
pub fn copy_region(rect: ImageRect, width: u32, height: u32) -> Option<(u32, u32, u32, u32)> {
    let x0 = rect.x.max(0) as i64;
    let y0 = rect.y.max(0) as i64;
    let x1 = (rect.x as i64 + rect.width.max(0) as i64).min(width as i64);
    let y1 = (rect.y as i64 + rect.height.max(0) as i64).min(height as i64);
    (x1 > x0 && y1 > y0).then(|| (x0 as u32, y0 as u32, (x1 - x0) as u32, (y1 - y0) as u32))
}

/// Texel layouts the layer turns into PNGs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Texels {
    /// R8G8B8A8 UNORM / SRGB: stored as they are (PNG samples are sRGB-encoded, as are an sRGB
    /// image's bytes; an app writing sRGB-encoded values into a UNORM image is the common case).
    Rgba8,
    /// B8G8R8A8 UNORM / SRGB.
    Bgra8,
    /// A2B10G10R10 UNORM: the top 8 of each 10 bits.
    A2b10g10r10,
    /// R16G16B16A16 SFLOAT: linear, encoded to sRGB.
    Rgba16f,
}

impl Texels {
    /// The layout of a `VkFormat` (raw value), None for formats the layer does not convert.
    pub fn of(format: i32) -> Option<Texels> {
        use ash::vk::Format as F;
        match ash::vk::Format::from_raw(format) {
            F::R8G8B8A8_UNORM | F::R8G8B8A8_SRGB => Some(Texels::Rgba8),
            F::B8G8R8A8_UNORM | F::B8G8R8A8_SRGB => Some(Texels::Bgra8),
            F::A2B10G10R10_UNORM_PACK32 => Some(Texels::A2b10g10r10),
            F::R16G16B16A16_SFLOAT => Some(Texels::Rgba16f),
            _ => None,
        }
    }
    pub fn bytes_per_texel(self) -> u64 {
        match self {
            Texels::Rgba16f => 8,
            _ => 4,
        }
    }
    /// Tightly packed texels (`count` of them) to 8-bit RGB samples (alpha dropped: an eye image's
    /// alpha is not meant to be seen). Short input yields what it holds.
    pub fn to_rgb8(self, texels: &[u8], count: usize) -> Vec<u8> {
        let n = self.bytes_per_texel() as usize;
        let texels = &texels[..(count * n).min(texels.len() / n * n)];
        let mut out = Vec::with_capacity(texels.len() / n * 3);
        for t in texels.chunks_exact(n) {
            match self {
                Texels::Rgba8 => out.extend_from_slice(&t[..3]),
                Texels::Bgra8 => out.extend_from_slice(&[t[2], t[1], t[0]]),
                Texels::A2b10g10r10 => {
                    let v = u32::from_le_bytes([t[0], t[1], t[2], t[3]]);
                    out.extend_from_slice(&[((v >> 2) & 0xFF) as u8, ((v >> 12) & 0xFF) as u8, ((v >> 22) & 0xFF) as u8]);
                }
                Texels::Rgba16f => {
                    for c in 0..3 {
                        out.push(linear_to_srgb8(f16_to_f32(u16::from_le_bytes([t[2 * c], t[2 * c + 1]]))));
                    }
                }
            }
        }
        out
    }
}

/// An IEEE half to f32.
pub fn f16_to_f32(h: u16) -> f32 {
    let sign = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exp = (h >> 10) & 0x1F;
    let frac = (h & 0x3FF) as f32;
    sign * match exp {
        0 => frac * 2f32.powi(-24),
        0x1F if frac == 0.0 => f32::INFINITY,
        0x1F => f32::NAN,
        e => (1.0 + frac / 1024.0) * 2f32.powi(e as i32 - 15),
    }
}

/// A linear value to an 8-bit sRGB-encoded sample (clamped; NaN is 0).
pub fn linear_to_srgb8(x: f32) -> u8 {
    let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) };
    let s = if x <= 0.003_130_8 { x * 12.92 } else { 1.055 * x.powf(1.0 / 2.4) - 0.055 };
    (s * 255.0).round() as u8
}

/// Whether every view in `expected` was captured (a frame's screenshot is complete).
pub fn views_complete<T: PartialEq>(expected: &[T], captured: &[T]) -> bool {
    !expected.is_empty() && expected.iter().all(|v| captured.contains(v))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trigger_is_looked_at_every_100_ms_at_most() {
        assert!(trigger_due(None, 5));
        assert!(!trigger_due(Some(1_000_000_000), 1_099_999_999));
        assert!(trigger_due(Some(1_000_000_000), 1_100_000_000));
        // A clock that went back never makes it due forever.
        assert!(!trigger_due(Some(10), 5));
    }

    #[test]
    fn a_touch_fires_once_and_an_old_file_never() {
        let mut w = TouchWatch::default();
        assert!(!w.fired(Some(100)), "a file from before the session");
        assert!(!w.fired(Some(100)));
        assert!(w.fired(Some(200)));
        assert!(!w.fired(Some(200)));
        assert!(!w.fired(None));
        assert!(w.fired(Some(300)), "a touch that makes the file again");
        let mut w = TouchWatch::default();
        assert!(!w.fired(None), "no file at the first look");
        assert!(w.fired(Some(5)), "made by a touch");
        assert!(w.fired(Some(6)));
    }

    #[test]
    fn runtime_files_and_pids() {
        let env = |k: &str| (k == "XDG_RUNTIME_DIR").then(|| "/run/user/7".to_string());
        let f = runtime_folder(&env).unwrap();
        assert_eq!(f, PathBuf::from("/run/user/7/stereoshim/screenshot"));
        assert_eq!(trigger_file(&f, 42), f.join("42.trigger"));
        assert_eq!(done_file(&f, 42), f.join("42.done.json"));
        assert_eq!(instance_pid(instance_file(&f, 42).file_name().unwrap().to_str().unwrap()), Some(42));
        assert_eq!(instance_pid("42.done.json"), None);
        assert_eq!(instance_pid(".json"), None);
        assert_eq!(instance_pid("x1.json"), None);
        assert_eq!((request_number("17\n"), request_number(""), request_number("junk")), (17, 0, 0));
    }

    #[test]
    fn pictures_folder_from_config_env_user_dirs_or_home() {
        let env = |pairs: &'static [(&'static str, &'static str)]| move |k: &str| pairs.iter().find(|(key, _)| *key == k).map(|(_, v)| v.to_string());
        assert_eq!(output_folder(" /shots ", &env(&[("HOME", "/h")]), None), Some(PathBuf::from("/shots")));
        assert_eq!(output_folder("", &env(&[("HOME", "/h"), ("XDG_PICTURES_DIR", "/p")]), None), Some(PathBuf::from("/p/stereoshim")));
        let dirs = "# written by xdg-user-dirs-update\nXDG_DESKTOP_DIR=\"$HOME/Desktop\"\nXDG_PICTURES_DIR=\"$HOME/Bilder\"\n";
        assert_eq!(output_folder("", &env(&[("HOME", "/h")]), Some(dirs)), Some(PathBuf::from("/h/Bilder/stereoshim")));
        assert_eq!(pictures_from_user_dirs("XDG_PICTURES_DIR=\"/data/pics\"", None), Some(PathBuf::from("/data/pics")));
        assert_eq!(pictures_from_user_dirs("XDG_PICTURES_DIR=\"relative\"", None), None);
        assert_eq!(pictures_from_user_dirs("XDG_PICTURES_DIR=\"$HOME/\"", Some(Path::new("/h"))), Some(PathBuf::from("/h")));
        assert_eq!(output_folder("", &env(&[("HOME", "/h"), ("XDG_PICTURES_DIR", "rel")]), None), Some(PathBuf::from("/h/Pictures/stereoshim")));
        assert_eq!(output_folder("", &env(&[]), None), None);
        assert_eq!(user_dirs_file(&env(&[("HOME", "/h")])), Some(PathBuf::from("/h/.config/user-dirs.dirs")));
        assert_eq!(user_dirs_file(&env(&[("HOME", "/h"), ("XDG_CONFIG_HOME", "/c")])), Some(PathBuf::from("/c/user-dirs.dirs")));
    }

    #[test]
    fn names_are_app_date_time_view() {
        assert_eq!(date_time(0), "19700101-000000-000");
        // 2026-11-23 00:14:05.123 UTC
        assert_eq!(date_time(1_795_392_845_123), "20261123-001405-123");
        // A leap day.
        assert_eq!(date_time(951_782_400_000), "20000229-000000-000");
        assert_eq!(file_stem("Hello XR/2", 0), "Hello_XR_2-19700101-000000-000");
        assert_eq!(app_part("..hidden"), "hidden");
        assert_eq!(app_part(" "), "app");
        assert_eq!(view_file("a-b", 1), "a-b-view-1.png");
    }

    #[test]
    fn regions_are_clipped_to_the_image() {
        let r = |x, y, width, height| ImageRect { x, y, width, height };
        assert_eq!(copy_region(r(0, 0, 100, 80), 200, 80), Some((0, 0, 100, 80)));
        assert_eq!(copy_region(r(100, 0, 100, 80), 200, 80), Some((100, 0, 100, 80)));
        assert_eq!(copy_region(r(150, -10, 100, 100), 200, 80), Some((150, 0, 50, 80)));
        assert_eq!(copy_region(r(200, 0, 10, 10), 200, 80), None);
        assert_eq!(copy_region(r(0, 0, -5, 10), 200, 80), None);
    }

    #[test]
    fn texels_become_rgb() {
        assert_eq!(Texels::of(ash::vk::Format::B8G8R8A8_SRGB.as_raw()), Some(Texels::Bgra8));
        assert_eq!(Texels::of(ash::vk::Format::R8G8B8A8_UNORM.as_raw()), Some(Texels::Rgba8));
        assert_eq!(Texels::of(ash::vk::Format::D32_SFLOAT.as_raw()), None);
        assert_eq!(Texels::Bgra8.to_rgb8(&[10, 20, 30, 255, 1, 2, 3, 4], 2), vec![30, 20, 10, 3, 2, 1]);
        assert_eq!(Texels::Rgba8.to_rgb8(&[10, 20, 30, 255, 1, 2, 3, 4], 1), vec![10, 20, 30]);
        let packed: u32 = (3 << 30) | (0x3FC << 20) | (0x200 << 10) | 0x004;
        assert_eq!(Texels::A2b10g10r10.to_rgb8(&packed.to_le_bytes(), 1), vec![1, 128, 255]);
        // 1.0, 0.5 (linear), 0.0 as halves.
        let h: Vec<u8> = [0x3C00u16, 0x3800, 0x0000, 0x3C00].iter().flat_map(|v| v.to_le_bytes()).collect();
        assert_eq!(Texels::Rgba16f.to_rgb8(&h, 1), vec![255, 188, 0]);
        assert_eq!(Texels::Rgba8.to_rgb8(&[1, 2, 3], 1), Vec::<u8>::new(), "short input");
    }

    #[test]
    fn halves_and_srgb() {
        assert_eq!(f16_to_f32(0x3C00), 1.0);
        assert_eq!(f16_to_f32(0xC000), -2.0);
        assert_eq!(f16_to_f32(0x0001), 2f32.powi(-24));
        assert!(f16_to_f32(0x7C00).is_infinite() && f16_to_f32(0x7C01).is_nan());
        assert_eq!((linear_to_srgb8(0.0), linear_to_srgb8(1.0), linear_to_srgb8(7.0), linear_to_srgb8(f32::NAN)), (0, 255, 255, 0));
        assert_eq!((linear_to_srgb8(0.215_861), linear_to_srgb8(0.212)), (128, 127));
    }

    #[test]
    fn a_frame_is_complete_with_every_view() {
        assert!(views_complete(&[0, 1], &[1, 0]));
        assert!(!views_complete(&[0, 1], &[0]));
        assert!(!views_complete(&[], &[0]));
    }
}
