//! Recognises the runtime's swapchain images whatever sits above the layer. A layer above
//! stereoshim (validation, capture tools, overlays) may wrap non-dispatchable handles: the
//! `VkImage`s the runtime reports from `xrEnumerateSwapchainImages` were created through the whole
//! chain and are then the top layer's wrapped values, while the command buffers stereoshim sees carry
//! the unwrapped handles below that layer. Handle values are therefore never compared across the
//! chain. Instead, the images are identified at their creation: while the runtime services
//! `xrCreateSwapchain`, the Vulkan half notes every image created on this thread (with the handle
//! *it* sees), and `xrEnumerateSwapchainImages` matches them to the reported images by index and
//! create parameters.
//!
//! Runtimes create (or import) a swapchain's images inside `xrCreateSwapchain`, on the calling
//! thread, in image-index order (the mock runtime, Monado's client compositor). A runtime that
//! creates them elsewhere or in another order falls back to handle equality, which holds when no
//! wrapping layer is above (`Match::Reported`).

use std::cell::RefCell;

/// A `VkImage` created on the app's device while a capture was open, as the Vulkan half saw it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CreatedImage {
    /// The handle below any wrapping layer above stereoshim (the one its command buffers carry).
    pub image: u64,
    pub format: i32,
    pub width: u32,
    pub height: u32,
    pub array_layers: u32,
    pub samples: u32,
    pub mip_levels: u32,
}

thread_local! {
    /// Open captures on this thread: a stack, so a nested `xrCreateSwapchain` (a layer below
    /// creating its own) keeps its images apart.
    static CAPTURES: RefCell<Vec<Vec<CreatedImage>>> = const { RefCell::new(Vec::new()) };
}

/// Runs `f` (the call down of `xrCreateSwapchain`) while noting the images created on this thread,
/// and returns them in creation order. The capture is closed even if `f` unwinds.
pub fn capture<R>(f: impl FnOnce() -> R) -> (R, Vec<CreatedImage>) {
    struct Open;
    impl Drop for Open {
        fn drop(&mut self) {
            end_capture();
        }
    }
    begin_capture();
    let open = Open;
    let r = f();
    std::mem::forget(open);
    (r, end_capture())
}

fn begin_capture() {
    CAPTURES.with(|c| c.borrow_mut().push(Vec::new()));
}

fn end_capture() -> Vec<CreatedImage> {
    CAPTURES.with(|c| c.borrow_mut().pop()).unwrap_or_default()
}

/// Called by the Vulkan half for every image it sees created; kept only inside a capture.
pub fn note_created(image: CreatedImage) {
    CAPTURES.with(|c| {
        if let Some(open) = c.borrow_mut().last_mut() {
            open.push(image);
        }
    });
}

/// What `xrCreateSwapchain` asked for, as far as the images must match it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Wanted {
    pub format: i64,
    pub width: u32,
    pub height: u32,
    pub array_size: u32,
    pub sample_count: u32,
    pub mip_count: u32,
}

impl Wanted {
    fn accepts(&self, i: &CreatedImage) -> bool {
        i64::from(i.format) == self.format
            && (i.width, i.height) == (self.width, self.height)
            && i.array_layers == self.array_size
            && i.samples == self.sample_count.max(1)
            && i.mip_levels == self.mip_count.max(1)
    }
}

/// How the layer knows the swapchain's images.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Match {
    /// The images created during `xrCreateSwapchain`, by index: what command buffers carry.
    Created(Vec<u64>),
    /// Nothing usable was created during the call (or not one image per index): the reported
    /// handles, correct unless a wrapping layer sits above. The string says why, for the log.
    Reported(Vec<u64>, String),
}

impl Match {
    pub fn images(&self) -> &[u64] {
        match self {
            Match::Created(v) | Match::Reported(v, _) => v,
        }
    }
}

/// Matches the images reported by `xrEnumerateSwapchainImages` (index order) with those created
/// during `xrCreateSwapchain`. Images of another shape created meanwhile (a runtime's own staging
/// images, say) are skipped; the rest must be exactly one per index.
pub fn match_images(wanted: &Wanted, created: &[CreatedImage], reported: &[u64]) -> Match {
    let candidates: Vec<u64> = created.iter().filter(|i| wanted.accepts(i)).map(|i| i.image).collect();
    if candidates.len() == reported.len() && !reported.is_empty() {
        return Match::Created(candidates);
    }
    let why = if created.is_empty() {
        "no image was created on the app's device during xrCreateSwapchain on its thread".to_string()
    } else {
        format!(
            "{} image(s) of the swapchain's shape were created during xrCreateSwapchain, {} reported",
            candidates.len(),
            reported.len()
        )
    };
    Match::Reported(reported.to_vec(), why)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn img(image: u64, width: u32, layers: u32) -> CreatedImage {
        CreatedImage { image, format: 43, width, height: 100, array_layers: layers, samples: 1, mip_levels: 1 }
    }
    const WANTED: Wanted = Wanted { format: 43, width: 200, height: 100, array_size: 2, sample_count: 1, mip_count: 1 };

    #[test]
    fn created_images_stand_for_the_reported_ones_by_index() {
        // Reported handles are a wrapping layer's (0xA…); the created ones are what command
        // buffers below it carry.
        let created = [img(11, 200, 2), img(12, 200, 2), img(13, 200, 2)];
        assert_eq!(match_images(&WANTED, &created, &[0xA1, 0xA2, 0xA3]), Match::Created(vec![11, 12, 13]));
    }

    #[test]
    fn images_of_another_shape_are_skipped() {
        let created = [img(5, 64, 1), img(11, 200, 2), img(6, 200, 1), img(12, 200, 2)];
        assert_eq!(match_images(&WANTED, &created, &[0xA1, 0xA2]), Match::Created(vec![11, 12]));
        let mut other_format = img(13, 200, 2);
        other_format.format = 44;
        assert_eq!(match_images(&WANTED, &[img(11, 200, 2), other_format], &[1, 2]).images(), &[1, 2]);
    }

    #[test]
    fn falls_back_to_the_reported_handles_with_a_reason() {
        let m = match_images(&WANTED, &[], &[7, 8]);
        assert!(matches!(&m, Match::Reported(v, why) if v == &[7, 8] && why.contains("no image")), "{m:?}");
        let m = match_images(&WANTED, &[img(11, 200, 2)], &[7, 8]);
        assert!(matches!(&m, Match::Reported(_, why) if why.contains("1 image(s)")), "{m:?}");
        assert!(matches!(match_images(&WANTED, &[], &[]), Match::Reported(..)));
    }

    #[test]
    fn captures_nest_and_only_record_inside() {
        note_created(img(1, 200, 2));
        begin_capture();
        note_created(img(2, 200, 2));
        begin_capture();
        note_created(img(3, 200, 2));
        assert_eq!(end_capture(), vec![img(3, 200, 2)]);
        note_created(img(4, 200, 2));
        assert_eq!(end_capture(), vec![img(2, 200, 2), img(4, 200, 2)]);
        assert!(end_capture().is_empty());
        // Another thread's capture is its own.
        let ((), seen) = capture(|| std::thread::spawn(|| note_created(img(9, 200, 2))).join().unwrap());
        assert!(seen.is_empty());
        // A capture is closed when the call down unwinds.
        let r = std::panic::catch_unwind(|| capture(|| -> () { panic!("down") }));
        assert!(r.is_err());
        note_created(img(5, 200, 2));
        let ((), seen) = capture(|| note_created(img(6, 200, 2)));
        assert_eq!(seen, vec![img(6, 200, 2)]);
    }
}
