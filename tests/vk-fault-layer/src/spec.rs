//! The fault specification (`VK_FAULT`) and the per-function call counters: pure, so the rule of
//! which call fails is unit-tested apart from the loader machinery.
#![forbid(unsafe_code)]

use std::sync::atomic::{AtomicU64, Ordering};

/// Every command the layer can fail, with the names it is reached by (core name first, then
/// aliases that share its counter: an app on Vulkan 1.0 calls `vkCreateRenderPass2KHR`).
pub const FUNCS: &[&[&str]] = &[
    &["vkCreateImage"],
    &["vkAllocateMemory"],
    &["vkCreateGraphicsPipelines"],
    &["vkCreateComputePipelines"],
    &["vkCreateShaderModule"],
    &["vkQueueSubmit"],
    &["vkCreateRenderPass"],
    &["vkCreateRenderPass2", "vkCreateRenderPass2KHR"],
    &["vkCreateImageView"],
    &["vkCreateBuffer"],
    &["vkCreateDescriptorPool"],
    &["vkAllocateDescriptorSets"],
    &["vkCreateFramebuffer"],
    &["vkCreateQueryPool"],
    &["vkAllocateCommandBuffers"],
    &["vkCreateFence"],
    &["vkCreatePipelineLayout"],
    &["vkCreateDescriptorSetLayout"],
    &["vkCreateSampler"],
    &["vkCreateCommandPool"],
];

/// Commands the lower instance hooks only to re-enter the chain from them (`VK_FAULT_REENTER`;
/// they cannot be failed): recording, submission 2 and destruction calls, where a layer above is
/// as likely to hold state across its call down as in the creation calls of [`FUNCS`].
pub const REENTER_ONLY: &[&[&str]] = &[
    &["vkQueueSubmit2", "vkQueueSubmit2KHR"],
    &["vkBeginCommandBuffer"],
    &["vkEndCommandBuffer"],
    &["vkCmdBeginRenderPass"],
    &["vkCmdBeginRenderPass2", "vkCmdBeginRenderPass2KHR"],
    &["vkCmdBeginRendering", "vkCmdBeginRenderingKHR"],
    &["vkCmdExecuteCommands"],
    &["vkCmdDraw"],
    &["vkCmdDrawIndexed"],
    &["vkDestroyImage"],
];

/// Index into [`REENTER_ONLY`] of a command name (core or alias).
pub fn reenter_only_index(name: &str) -> Option<usize> {
    REENTER_ONLY.iter().position(|names| names.contains(&name))
}

/// The core name of a command the layer can re-enter from (one of [`FUNCS`] or
/// [`REENTER_ONLY`], core or alias).
pub fn reentry_name(name: &str) -> Option<&'static str> {
    FUNCS.iter().chain(REENTER_ONLY).find(|names| names.contains(&name)).map(|names| names[0])
}

/// Parses `VK_FAULT_REENTER`: a comma-separated list of command names (aliases allowed) from
/// whose calls the lower instance calls back up to the top of the chain; returns their core
/// names. A name the layer does not hook is an error (a typo must never pass as "re-entered
/// nowhere").
pub fn parse_reenter(text: &str) -> Result<Vec<&'static str>, String> {
    let mut names = Vec::new();
    for item in text.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let name = reentry_name(item).ok_or_else(|| format!("{item:?} is not a command this layer can re-enter from"))?;
        if !names.contains(&name) {
            names.push(name);
        }
    }
    Ok(names)
}

/// Index into [`FUNCS`] of a command name (core or alias).
pub fn func_index(name: &str) -> Option<usize> {
    FUNCS.iter().position(|names| names.contains(&name))
}

/// Who made a call that reached the layer's lower instance: the app (or the runtime, which
/// calls on the app's device like the app does), i.e. a call the marker instance above
/// stereoshim saw; or the layer between the two instances (stereoshim), for its own objects.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Origin {
    App,
    Layer,
}

/// Which calls of a function a rule counts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Counted {
    All,
    Only(Origin),
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Rule {
    pub func: usize,
    pub counted: Counted,
    /// The 0-based call index among the counted calls; None: every counted call fails.
    pub index: Option<u64>,
    pub result: i32,
}

/// The `VkResult` error codes a rule may name (those a creation or submission may return).
const RESULTS: &[(&str, i32)] = &[
    ("VK_ERROR_OUT_OF_HOST_MEMORY", -1),
    ("VK_ERROR_OUT_OF_DEVICE_MEMORY", -2),
    ("VK_ERROR_INITIALIZATION_FAILED", -3),
    ("VK_ERROR_DEVICE_LOST", -4),
    ("VK_ERROR_FRAGMENTED_POOL", -12),
    ("VK_ERROR_UNKNOWN", -13),
    ("VK_ERROR_OUT_OF_POOL_MEMORY", -1000069000),
    ("VK_ERROR_INVALID_SHADER_NV", -1000012000),
];

pub fn result_name(code: i32) -> String {
    RESULTS.iter().find(|(_, c)| *c == code).map_or_else(|| code.to_string(), |(n, _)| n.to_string())
}

/// Parses `F[@[app:|layer:]K][=RESULT],…` (e.g.
/// `vkCreateImage@2=VK_ERROR_OUT_OF_DEVICE_MEMORY,vkQueueSubmit@layer:0=VK_ERROR_DEVICE_LOST`).
/// Without `@K` every counted call fails; `@app` / `@layer` alone count only that origin.
pub fn parse(text: &str) -> Result<Vec<Rule>, String> {
    let mut rules = Vec::new();
    for item in text.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let (call, result) = item.split_once('=').ok_or_else(|| format!("{item:?}: no =RESULT"))?;
        let result = RESULTS
            .iter()
            .find(|(n, _)| *n == result)
            .map(|(_, c)| *c)
            .ok_or_else(|| format!("{item:?}: unknown result {result:?}"))?;
        let (name, selector) = match call.split_once('@') {
            Some((n, s)) => (n, Some(s)),
            None => (call, None),
        };
        let func = func_index(name).ok_or_else(|| format!("{item:?}: {name} is not a command this layer can fail"))?;
        let (counted, index) = match selector {
            None => (Counted::All, None),
            Some(s) => {
                let (counted, k) = match s.split_once(':') {
                    Some(("app", k)) => (Counted::Only(Origin::App), Some(k)),
                    Some(("layer", k)) => (Counted::Only(Origin::Layer), Some(k)),
                    Some(_) => return Err(format!("{item:?}: origin must be app or layer")),
                    None if s == "app" => (Counted::Only(Origin::App), None),
                    None if s == "layer" => (Counted::Only(Origin::Layer), None),
                    None => (Counted::All, Some(s)),
                };
                let index = k.map(|k| k.parse::<u64>().map_err(|_| format!("{item:?}: call index {k:?} is not a number"))).transpose()?;
                (counted, index)
            }
        };
        rules.push(Rule { func, counted, index, result });
    }
    Ok(rules)
}

/// Calls seen so far per function: all of them, the app's, the layer's.
pub struct Counters {
    counts: Vec<[AtomicU64; 3]>,
}

impl Default for Counters {
    fn default() -> Self {
        Counters { counts: FUNCS.iter().map(|_| Default::default()).collect() }
    }
}

/// What [`Counters::next`] decided for one call.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Call {
    /// The call's index among all calls of its function, and among those of its origin.
    pub index: u64,
    pub origin_index: u64,
    /// The error to return instead of calling down, if a rule hits this call.
    pub fail: Option<i32>,
}

impl Counters {
    /// Counts one call of `func` from `origin` and applies the first rule that hits it.
    pub fn next(&self, rules: &[Rule], func: usize, origin: Origin) -> Call {
        let slot = match origin {
            Origin::App => 1,
            Origin::Layer => 2,
        };
        let index = self.counts[func][0].fetch_add(1, Ordering::SeqCst);
        let origin_index = self.counts[func][slot].fetch_add(1, Ordering::SeqCst);
        let fail = rules
            .iter()
            .filter(|r| r.func == func)
            .find(|r| match r.counted {
                Counted::All => r.index.is_none() || r.index == Some(index),
                Counted::Only(o) => o == origin && (r.index.is_none() || r.index == Some(origin_index)),
            })
            .map(|r| r.result);
        Call { index, origin_index, fail }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_the_documented_forms() {
        let r = parse("vkCreateImage@2=VK_ERROR_OUT_OF_DEVICE_MEMORY, vkQueueSubmit@layer:0=VK_ERROR_DEVICE_LOST,vkCreateFence=VK_ERROR_OUT_OF_HOST_MEMORY,vkCreateRenderPass2KHR@app=VK_ERROR_UNKNOWN").unwrap();
        assert_eq!(r[0], Rule { func: 0, counted: Counted::All, index: Some(2), result: -2 });
        assert_eq!(r[1], Rule { func: 5, counted: Counted::Only(Origin::Layer), index: Some(0), result: -4 });
        assert_eq!(r[2], Rule { func: func_index("vkCreateFence").unwrap(), counted: Counted::All, index: None, result: -1 });
        assert_eq!(r[3].func, func_index("vkCreateRenderPass2").unwrap(), "an alias shares its command's counter");
        assert_eq!(r[3].counted, Counted::Only(Origin::App));
        assert!(parse("").unwrap().is_empty());
    }

    #[test]
    fn reenter_names() {
        assert_eq!(parse_reenter("vkQueueSubmit, vkQueueSubmit2KHR,vkCmdBeginRenderPass2KHR,vkCreateImage,vkQueueSubmit").unwrap(), ["vkQueueSubmit", "vkQueueSubmit2", "vkCmdBeginRenderPass2", "vkCreateImage"]);
        assert!(parse_reenter("").unwrap().is_empty());
        assert!(parse_reenter("vkCreateImage,vkCreateDevice").is_err(), "no device to re-enter on yet");
        assert!(parse_reenter("vkCmdBeginRenderpass").is_err());
        for names in FUNCS {
            assert!(reenter_only_index(names[0]).is_none(), "{} is in both lists", names[0]);
        }
    }

    #[test]
    fn rejects_what_it_cannot_honour() {
        for bad in ["vkCreateImage", "vkCreateImage=NOPE", "vkDestroyImage=VK_ERROR_UNKNOWN", "vkCreateImage@x=VK_ERROR_UNKNOWN", "vkCreateImage@gpu:1=VK_ERROR_UNKNOWN"] {
            assert!(parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn counts_per_function_and_origin() {
        let rules = parse("vkCreateImage@2=VK_ERROR_OUT_OF_DEVICE_MEMORY,vkCreateBuffer@layer:1=VK_ERROR_OUT_OF_DEVICE_MEMORY").unwrap();
        let c = Counters::default();
        let image = func_index("vkCreateImage").unwrap();
        let buffer = func_index("vkCreateBuffer").unwrap();
        let fails: Vec<bool> = [Origin::App, Origin::Layer, Origin::App, Origin::App].iter().map(|o| c.next(&rules, image, *o).fail.is_some()).collect();
        assert_eq!(fails, [false, false, true, false], "index 2 across origins");
        let b: Vec<Call> = [Origin::Layer, Origin::App, Origin::Layer, Origin::Layer].iter().map(|o| c.next(&rules, buffer, *o)).collect();
        assert_eq!(b.iter().map(|x| x.fail.is_some()).collect::<Vec<_>>(), [false, false, true, false], "the layer's second call only");
        assert_eq!((b[2].index, b[2].origin_index), (2, 1));
    }
}
