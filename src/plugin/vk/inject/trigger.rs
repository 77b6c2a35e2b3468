//! When an injection point is reached and whether it counts: the pure state machine behind
//! `vk::chassis::on_trigger`. A pass counts once — at its beginning, or, when it loads its depth,
//! at its first depth clear or (uncleared) at its end; resumed and suspended dynamic renderings
//! count once over all their parts.
#![forbid(unsafe_code)]

use crate::core::pass::NotMasked;
use crate::core::rect::PixelRect;
use crate::track::cmd::PassInstance;
use crate::track::eye_pass;

/// Why the injection point may have been reached.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Trigger {
    /// A render pass instance / rendering just began (`secondary`: its contents are recorded in
    /// secondary command buffers).
    Begin { secondary: bool },
    /// vkCmdNextSubpass: a later subpass may be the first to use (and clear) the depth attachment.
    NextSubpass { secondary: bool },
    /// vkCmdClearAttachments cleared the depth attachment to this value over these rects.
    Clear { depth: f32, rects: Vec<PixelRect> },
    /// The pass is about to end (nothing is drawn): a deferred pass that was never cleared counts.
    End,
}

impl Trigger {
    /// Whether the pass's contents (from here) are secondary command buffers.
    pub fn secondary_contents(&self) -> bool {
        matches!(self, Trigger::Begin { secondary: true } | Trigger::NextSubpass { secondary: true })
    }
}

/// What a trigger means for the pass's counting.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Decision {
    /// This trigger is the pass's one count (injected or not).
    pub counts: bool,
    /// The pass is deferred from now on (it loads its depth: a later clear may still come).
    pub defer: bool,
    /// The pass is no longer deferred.
    pub undefer: bool,
}

/// Decides for `trigger` on `pass`, given the eye-pass test's result and whether the pass was
/// deferred before.
pub(crate) fn decide(trigger: &Trigger, pass: &PassInstance, plan: Result<(), NotMasked>, deferred: bool) -> Decision {
    let rendering = pass.rendering.as_ref();
    let none = Decision { counts: false, defer: false, undefer: false };
    match trigger {
        Trigger::Begin { .. } if rendering.is_some_and(|r| r.resuming()) => none,
        Trigger::Begin { .. } => {
            let defer = plan == Err(NotMasked::DepthNotCleared) && eye_pass::depth_loads(pass);
            Decision { counts: !defer, defer, undefer: !defer }
        }
        Trigger::NextSubpass { .. } => none,
        Trigger::Clear { .. } => Decision { counts: deferred, defer: false, undefer: deferred },
        Trigger::End if rendering.is_some_and(|r| r.suspending()) => none,
        Trigger::End => Decision { counts: deferred, defer: false, undefer: deferred },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::track::cmd::PassKind;

    fn pass() -> PassInstance {
        PassInstance {
            kind: PassKind::RenderPass,
            render_area: crate::track::cmd::Rect { x: 0, y: 0, width: 8, height: 8 },
            subpass: 0,
            render_pass: None,
            framebuffer: None,
            attachments: Vec::new(),
            clear_values: Vec::new(),
            rendering: None,
            flow_at: None,
        }
    }

    #[test]
    fn a_cleared_pass_counts_at_its_beginning_only() {
        let p = pass();
        let begin = decide(&Trigger::Begin { secondary: false }, &p, Ok(()), false);
        assert_eq!(begin, Decision { counts: true, defer: false, undefer: true });
        assert!(!decide(&Trigger::NextSubpass { secondary: false }, &p, Ok(()), false).counts);
        assert!(!decide(&Trigger::Clear { depth: 1.0, rects: vec![] }, &p, Ok(()), false).counts, "not deferred: already counted");
        assert!(!decide(&Trigger::End, &p, Ok(()), false).counts);
    }

    #[test]
    fn a_deferred_pass_counts_at_its_clear_or_its_end() {
        let p = pass();
        // Not loading a depth attachment (no render pass tracked): nothing to defer.
        let d = decide(&Trigger::Begin { secondary: false }, &p, Err(NotMasked::DepthNotCleared), false);
        assert!(d.counts && !d.defer);
        let clear = decide(&Trigger::Clear { depth: 0.0, rects: vec![] }, &p, Ok(()), true);
        assert_eq!(clear, Decision { counts: true, defer: false, undefer: true });
        let end = decide(&Trigger::End, &p, Err(NotMasked::DepthNotCleared), true);
        assert_eq!(end, Decision { counts: true, defer: false, undefer: true });
    }

    #[test]
    fn secondary_contents() {
        assert!(Trigger::Begin { secondary: true }.secondary_contents());
        assert!(!Trigger::Clear { depth: 1.0, rects: vec![] }.secondary_contents());
        assert!(!Trigger::End.secondary_contents());
    }
}
