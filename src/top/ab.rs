//! `stereoshim top`'s live A/B: features switched off (A) and on (B) every `period` frames in the
//! running app, as `examples/bench` does for xr-scene, through `top`'s live settings (so the
//! config file is never touched by it). Each frame's line says which features it was recorded
//! with, so frames are sorted into A and B by what the layer really did, not by when the switch
//! was asked for; the first frames of each stretch are left out (the switch's own cost).
//! The speed-up is median GPU time A / median GPU time B, with its spread over the cycles.
//! Pure: `top` feeds frames in and writes the settings it is handed.
#![forbid(unsafe_code)]

use super::model::{median, FrameView};

/// The features that can be switched while the app runs (key, name). The upscale and the view
/// tricks change the app's image sizes: they apply at the next session, not frame by frame.
pub const SWITCHABLE: [(&str, &str); 3] = [("mask.enabled", "mask"), ("foveation.enabled", "foveation"), ("far_field.enabled", "far field")];

/// Frames left out after a stretch starts (the first frame after a switch builds the feature's
/// objects; its neighbours may still share GPU time with the other setting's frames).
pub const SETTLE_FRAMES: u64 = 3;

/// How many frames the layer may take to show a switch before the A/B gives up (the layer looks
/// at the live settings every 100 ms: even at 10 fps this is 20 looks).
pub const APPLY_WITHIN_FRAMES: u64 = 200;

/// Whether `f` was recorded with `key` on.
pub fn frame_has(f: &FrameView, key: &str) -> Option<bool> {
    match key {
        "mask.enabled" => Some(f.mask),
        "foveation.enabled" => Some(f.foveation),
        "far_field.enabled" => Some(f.far_field),
        _ => None,
    }
}

/// One side of a comparison: a value for each switched key.
#[derive(Clone, Debug, PartialEq)]
pub struct Arm {
    pub settings: Vec<(&'static str, bool)>,
}

impl Arm {
    fn matches(&self, f: &FrameView) -> bool {
        self.settings.iter().all(|(k, v)| frame_has(f, k) == Some(*v))
    }
}

/// A against B, named for what B adds.
#[derive(Clone, Debug, PartialEq)]
pub struct Comparison {
    pub label: String,
    pub a: Arm,
    pub b: Arm,
}

/// The comparisons for features `on` (keys of [`SWITCHABLE`]): all of them off against on, and,
/// with `each`, every one off against all on (what it adds on top of the others).
pub fn plan(on: &[&'static str], each: bool) -> Vec<Comparison> {
    let name = |k: &str| SWITCHABLE.iter().find(|(key, _)| *key == k).map_or(k.to_string(), |(_, n)| n.to_string());
    let all_on = Arm { settings: on.iter().map(|k| (*k, true)).collect() };
    if !each {
        return vec![Comparison {
            label: on.iter().map(|k| name(k)).collect::<Vec<_>>().join(" + "),
            a: Arm { settings: on.iter().map(|k| (*k, false)).collect() },
            b: all_on,
        }];
    }
    on.iter()
        .map(|k| Comparison {
            label: format!("{} on top of the others", name(k)),
            a: Arm { settings: on.iter().map(|o| (*o, o != k)).collect() },
            b: all_on.clone(),
        })
        .collect()
}

/// One comparison's outcome.
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome {
    pub label: String,
    /// The key B adds (each-feature comparisons), None for all-features.
    pub feature: Option<&'static str>,
    pub median_a_ms: f64,
    pub median_b_ms: f64,
    /// median A / median B over every kept frame.
    pub speedup: f64,
    /// The lowest and highest per-cycle speed-up.
    pub spread: (f64, f64),
    pub cycles: usize,
    pub frames: (usize, usize),
}

impl Outcome {
    /// Whether B is faster than A in every cycle.
    pub fn pays(&self) -> bool {
        self.spread.0 > 1.0
    }

    pub fn line(&self) -> String {
        format!(
            "{}: {:.2}x ({:.2}-{:.2} over {} cycles), {:.2} -> {:.2} ms",
            self.label, self.speedup, self.spread.0, self.spread.1, self.cycles, self.median_a_ms, self.median_b_ms
        )
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Side {
    A,
    B,
}

/// A running A/B.
#[derive(Debug)]
pub struct AbRun {
    comparisons: Vec<Comparison>,
    /// Which comparisons compare one feature (its key).
    features: Vec<Option<&'static str>>,
    period: u64,
    cycles: usize,
    current: usize,
    side: Side,
    /// Frames of the current stretch seen with its settings applied.
    applied: u64,
    /// Frames since the current stretch's settings were handed out.
    waited: u64,
    /// Per comparison, per cycle: (A times, B times).
    samples: Vec<Vec<(Vec<f64>, Vec<f64>)>>,
    pub outcomes: Vec<Outcome>,
    /// Why the A/B stopped early.
    pub failed: Option<String>,
}

impl AbRun {
    pub fn new(comparisons: Vec<Comparison>, each: bool, period: u64, cycles: usize) -> AbRun {
        let features = comparisons.iter().map(|c| if each { c.b.settings.iter().zip(&c.a.settings).find(|(b, a)| b.1 != a.1).map(|(b, _)| b.0) } else { None }).collect();
        let n = comparisons.len();
        AbRun {
            comparisons,
            features,
            period: period.max(SETTLE_FRAMES + 2),
            cycles: cycles.max(1),
            current: 0,
            side: Side::A,
            applied: 0,
            waited: 0,
            samples: vec![Vec::new(); n],
            outcomes: Vec::new(),
            failed: None,
        }
    }

    pub fn finished(&self) -> bool {
        self.failed.is_some() || self.current >= self.comparisons.len()
    }

    /// The settings the layer should run with now (None once finished).
    pub fn settings(&self) -> Option<&[(&'static str, bool)]> {
        let c = self.comparisons.get(self.current).filter(|_| self.failed.is_none())?;
        Some(match self.side {
            Side::A => &c.a.settings,
            Side::B => &c.b.settings,
        })
    }

    /// Where the A/B is, for the screen.
    pub fn status(&self) -> String {
        if let Some(e) = &self.failed {
            return format!("A/B stopped: {e}");
        }
        match self.comparisons.get(self.current) {
            None => "A/B done".to_string(),
            Some(c) => format!(
                "A/B {}/{}: {} - cycle {}/{}, {} {}/{}",
                self.current + 1,
                self.comparisons.len(),
                c.label,
                self.samples[self.current].len().max(1).min(self.cycles),
                self.cycles,
                if self.side == Side::A { "off" } else { "on" },
                self.applied,
                self.period
            ),
        }
    }

    /// Feeds a frame; returns true when the settings to run with changed.
    pub fn frame(&mut self, f: &FrameView) -> bool {
        if self.finished() {
            return false;
        }
        let c = &self.comparisons[self.current];
        let arm = if self.side == Side::A { &c.a } else { &c.b };
        if !arm.matches(f) {
            self.waited += 1;
            if self.applied == 0 && self.waited > APPLY_WITHIN_FRAMES {
                self.failed = Some(format!("the app's frames did not show the switch within {APPLY_WITHIN_FRAMES} frames (live.enabled off, or the environment sets these keys?)"));
                return true;
            }
            return false;
        }
        self.applied += 1;
        let cycles = &mut self.samples[self.current];
        if self.side == Side::A && self.applied == 1 {
            cycles.push((Vec::new(), Vec::new()));
        }
        if self.applied > SETTLE_FRAMES {
            if let (Some(ms), Some(cycle)) = (f.gpu_ms, cycles.last_mut()) {
                match self.side {
                    Side::A => cycle.0.push(ms),
                    Side::B => cycle.1.push(ms),
                }
            }
        }
        if self.applied < self.period {
            return false;
        }
        self.applied = 0;
        self.waited = 0;
        match self.side {
            Side::A => self.side = Side::B,
            Side::B => {
                self.side = Side::A;
                if self.samples[self.current].len() >= self.cycles {
                    self.conclude();
                    self.current += 1;
                }
            }
        }
        true
    }

    fn conclude(&mut self) {
        let i = self.current;
        let cycles = &self.samples[i];
        let mut ratios: Vec<f64> = cycles
            .iter()
            .filter_map(|(a, b)| {
                let (ma, mb) = (median(&mut a.clone())?, median(&mut b.clone())?);
                (mb > 0.0).then_some(ma / mb)
            })
            .collect();
        let mut all_a: Vec<f64> = cycles.iter().flat_map(|c| c.0.iter().copied()).collect();
        let mut all_b: Vec<f64> = cycles.iter().flat_map(|c| c.1.iter().copied()).collect();
        let (na, nb) = (all_a.len(), all_b.len());
        match (median(&mut all_a), median(&mut all_b), ratios.is_empty()) {
            (Some(ma), Some(mb), false) if mb > 0.0 => {
                ratios.sort_by(|a, b| a.total_cmp(b));
                self.outcomes.push(Outcome {
                    label: self.comparisons[i].label.clone(),
                    feature: self.features[i],
                    median_a_ms: ma,
                    median_b_ms: mb,
                    speedup: ma / mb,
                    spread: (ratios[0], ratios[ratios.len() - 1]),
                    cycles: ratios.len(),
                    frames: (na, nb),
                });
            }
            _ => self.failed = Some(format!("{}: no GPU times in the frames (the layer's GPU timer did not report)", self.comparisons[i].label)),
        }
    }

    /// The features that cost more than they save (each-feature A/Bs whose B was not faster in
    /// every cycle): what "keep only what pays" turns off.
    pub fn not_paying(&self) -> Vec<&'static str> {
        self.outcomes.iter().filter(|o| !o.pays()).filter_map(|o| o.feature).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(n: u64, mask: bool, foveation: bool, ms: f64) -> FrameView {
        FrameView { frame: n, time: n as f64 / 90.0, gpu_ms: Some(ms), mask, foveation, ..Default::default() }
    }

    /// Drives `run` like a layer that applies each switch `lag` frames late, with GPU time
    /// `cost(mask, foveation)` and a little noise.
    fn drive(run: &mut AbRun, lag: u64, cost: impl Fn(bool, bool) -> f64) -> u64 {
        let mut n = 0;
        let mut current = (true, true);
        let wanted = |run: &AbRun| {
            run.settings().map(|s| {
                let get = |k: &str| s.iter().find(|(key, _)| *key == k).is_none_or(|(_, v)| *v);
                (get("mask.enabled"), get("foveation.enabled"))
            })
        };
        // `top` writes the first stretch's settings when the A/B starts.
        let mut pending: Option<(u64, (bool, bool))> = wanted(run).map(|s| (lag, s));
        while !run.finished() && n < 100_000 {
            if let Some((at, s)) = pending {
                if n >= at {
                    current = s;
                    pending = None;
                }
            }
            let noise = [0.0, 0.05, -0.05, 0.02][(n % 4) as usize];
            if run.frame(&frame(n, current.0, current.1, cost(current.0, current.1) + noise)) {
                pending = wanted(run).map(|s| (n + lag, s));
            }
            n += 1;
        }
        n
    }

    #[test]
    fn all_features_off_against_on() {
        let on = ["mask.enabled", "foveation.enabled"];
        let mut run = AbRun::new(plan(&on, false), false, 20, 3);
        assert_eq!(run.settings().unwrap(), &[("mask.enabled", false), ("foveation.enabled", false)]);
        drive(&mut run, 4, |m, f| 10.0 - if m { 2.0 } else { 0.0 } - if f { 3.0 } else { 0.0 });
        assert!(run.failed.is_none(), "{:?}", run.failed);
        assert_eq!(run.outcomes.len(), 1);
        let o = &run.outcomes[0];
        assert!((o.speedup - 2.0).abs() < 0.05, "{}", o.line());
        assert!(o.spread.0 > 1.9 && o.spread.1 < 2.1 && o.cycles == 3, "{}", o.line());
        assert_eq!(o.label, "mask + foveation");
        // Settle frames left out: per cycle and side, period − settle frames.
        assert_eq!(o.frames, (3 * 17, 3 * 17));
    }

    #[test]
    fn each_feature_on_top_of_the_others_and_what_pays() {
        let on = ["mask.enabled", "foveation.enabled"];
        let mut run = AbRun::new(plan(&on, true), true, 12, 2);
        // The mask saves 2 ms; foveation costs 1 ms more than it saves.
        drive(&mut run, 2, |m, f| 10.0 - if m { 2.0 } else { 0.0 } + if f { 1.0 } else { 0.0 });
        assert!(run.failed.is_none(), "{:?}", run.failed);
        let lines: Vec<String> = run.outcomes.iter().map(Outcome::line).collect();
        assert_eq!(run.outcomes.len(), 2, "{lines:?}");
        assert_eq!(run.outcomes[0].feature, Some("mask.enabled"));
        assert!(run.outcomes[0].pays() && run.outcomes[0].speedup > 1.2, "{lines:?}");
        assert!(!run.outcomes[1].pays() && run.outcomes[1].speedup < 1.0, "{lines:?}");
        assert_eq!(run.not_paying(), vec!["foveation.enabled"]);
    }

    #[test]
    fn a_switch_never_applied_stops_the_ab() {
        let mut run = AbRun::new(plan(&["mask.enabled"], false), false, 10, 2);
        for n in 0..=APPLY_WITHIN_FRAMES + 1 {
            run.frame(&frame(n, true, false, 5.0));
        }
        assert!(run.finished() && run.failed.as_deref().unwrap_or("").contains("did not show the switch"), "{:?}", run.failed);
        assert!(run.settings().is_none());
    }

    #[test]
    fn frames_without_gpu_time_say_so() {
        let mut run = AbRun::new(plan(&["mask.enabled"], false), false, 6, 1);
        let mut n = 0;
        while !run.finished() && n < 1000 {
            let on = run.settings().is_some_and(|s| s[0].1);
            run.frame(&FrameView { frame: n, mask: on, gpu_ms: None, ..Default::default() });
            n += 1;
        }
        assert!(run.failed.as_deref().unwrap_or("").contains("no GPU times"), "{:?}", run.failed);
    }
}
