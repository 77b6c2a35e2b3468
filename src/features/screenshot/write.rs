//! Writing a screenshot (on the layer's thread, never the app's): one PNG per view, each written
//! to a temporary name and renamed so no one ever sees half a picture, a JSON beside them (frame,
//! views, rects), and the result file in the runtime folder that `stereoshim screenshot --wait`
//! waits for. A folder that cannot be written is a log line and an error in the result file.
#![forbid(unsafe_code)]

use super::rules;
use super::vk::{Request, ViewCopy};
use serde_json::json;
use std::io::Write;
use std::path::Path;

/// One view's picture: 8-bit RGB samples of its region.
pub(super) struct Picture {
    view: ViewCopy,
    rgb: Vec<u8>,
}

impl Picture {
    pub(super) fn new(view: &ViewCopy, rgb: Vec<u8>) -> Picture {
        Picture { view: *view, rgb }
    }
}

/// Encodes 8-bit RGB samples as a PNG.
pub fn encode_png(width: u32, height: u32, rgb: &[u8]) -> Result<Vec<u8>, String> {
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, width, height);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc.write_header().map_err(|e| e.to_string())?;
    w.write_image_data(rgb).map_err(|e| e.to_string())?;
    w.finish().map_err(|e| e.to_string())?;
    Ok(out)
}

fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        drop(f);
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Writes the pictures of `frame` for `request`; logs and reports (result file) any failure.
pub(super) fn write(request: &Request, frame: u64, mut pictures: Vec<Picture>) {
    pictures.sort_by_key(|p| p.view.view);
    let unix_ms = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map(|d| d.as_millis() as u64).unwrap_or(0);
    let stem = rules::file_stem(&request.app, unix_ms);
    let result = (|| -> Result<serde_json::Value, String> {
        let dir = request.dir.as_ref().ok_or("no folder for screenshots: set screenshot.dir (none of XDG_PICTURES_DIR, HOME is set)")?;
        if pictures.is_empty() {
            return Err("nothing was copied (see the warnings above)".into());
        }
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        let mut views = Vec::new();
        for p in &pictures {
            let (x, y, w, h) = p.view.region;
            let file = dir.join(if p.view.display { rules::display_file(&stem, p.view.view) } else { rules::view_file(&stem, p.view.view) });
            let png = encode_png(w, h, &p.rgb)?;
            write_atomic(&file, &png).map_err(|e| format!("{}: {e}", file.display()))?;
            views.push(json!({
                "view": p.view.view, "file": file, "width": w, "height": h,
                "image_rect": { "x": x, "y": y, "width": w, "height": h },
                "image_array_index": p.view.layer, "format": p.view.format, "swapchain": p.view.swapchain, "display": p.view.display,
            }));
        }
        let doc = json!({ "app": request.app, "frame": frame, "time_ms": unix_ms, "views": views });
        let side = dir.join(format!("{stem}.json"));
        write_atomic(&side, serde_json::to_string_pretty(&doc).unwrap_or_default().as_bytes()).map_err(|e| format!("{}: {e}", side.display()))?;
        Ok(doc)
    })();
    let mut done = match result {
        Ok(doc) => {
            tracing::info!("screenshot of frame {frame}: {} view(s) in {}", pictures.len(), request.dir.as_deref().unwrap_or(Path::new("")).display());
            doc
        }
        Err(e) => {
            tracing::warn!("screenshot of frame {frame} not written: {e}");
            json!({ "app": request.app, "frame": frame, "error": e })
        }
    };
    done["request"] = request.token.into();
    if let Some(path) = &request.done {
        if let Err(e) = crate::manifests::private_fs::write_private(path, done.to_string().as_bytes()) {
            tracing::warn!("screenshot: cannot write {}: {e}", path.display());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn png_round_trip_and_atomic_write() {
        let png = encode_png(2, 1, &[1, 2, 3, 4, 5, 6]).unwrap();
        let mut r = png::Decoder::new(std::io::Cursor::new(&png)).read_info().unwrap();
        let mut buf = vec![0; r.output_buffer_size().unwrap()];
        let info = r.next_frame(&mut buf).unwrap();
        assert_eq!((info.width, info.height, &buf[..6]), (2, 1, &[1u8, 2, 3, 4, 5, 6][..]));
        assert!(encode_png(2, 2, &[0; 3]).is_err(), "too few samples");
        let dir = std::env::temp_dir().join(format!("stereoshim-write-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("a.png");
        write_atomic(&f, b"x").unwrap();
        assert_eq!(std::fs::read(&f).unwrap(), b"x");
        assert!(!dir.join("a.png.tmp").exists());
        assert!(write_atomic(&dir.join("missing/a.png"), b"x").is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
