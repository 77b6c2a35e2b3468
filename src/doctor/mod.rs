//! `stereoshim doctor`: checks that the layer can work on this machine — the OpenXR loader and
//! active runtime, stereoshim's manifests, the Vulkan half, the GPU's capabilities per feature, the
//! effective config, known conflicts — and reports each as ok / warning / error with a one-line
//! fix. `gather` reads the facts, `rules` (pure) judges them, this module orders and prints them;
//! `container` adds the checks that matter inside Steam's game container.

pub mod container;
pub mod gather;
pub mod rules;

pub use rules::{Finding, Status};
use std::path::PathBuf;

/// What the command was asked.
#[derive(Clone, Debug, Default)]
pub struct Options {
    pub app: Option<String>,
    pub config: Option<PathBuf>,
}

/// Every finding, in the order checked.
#[derive(Clone, Debug, Default)]
pub struct Report {
    pub findings: Vec<Finding>,
}

/// Runs every check. The probes that load foreign code run on threads of their own, with a time
/// limit (`gather::bounded`); nothing here panics on an odd environment.
pub fn run(opts: &Options) -> Report {
    let env = |k: &str| std::env::var(k).ok();
    let (ours, others) = gather::layers();
    // Before any probe: it edits VK_ADD_LAYER_PATH of this process as the OpenXR half would.
    let half = gather::vulkan_half(&ours);
    let vk = gather::bounded("Vulkan", gather::PROBE_LIMIT, crate::vk::probe::probe);
    let runtime = gather::runtime();
    // After the Vulkan probe: the instance brings every implicit OpenXR layer in, stereoshim's too.
    let xr = gather::bounded("OpenXR", gather::PROBE_LIMIT, crate::xr::probe::probe);
    let config = gather::config(opts.config.as_deref(), opts.app.as_deref());
    let installed = ours.iter().any(|m| m.implicit);
    let xr_layers = xr.as_ref().ok().and_then(|f| f.layers.as_ref().ok()).map(Vec::as_slice);
    let vk_layers = vk.as_ref().ok().filter(|v| v.instance_error.is_none() || !v.layers.is_empty()).map(|v| v.layers.as_slice());
    let mut findings = Vec::new();
    findings.extend(rules::openxr_loader(&xr));
    findings.extend(rules::runtime(&runtime));
    findings.extend(rules::instance(&xr, &runtime));
    findings.extend(rules::extensions(&xr, &runtime));
    findings.extend(rules::manifests(&ours, env(crate::manifests::DISABLE_ENV).is_some()));
    findings.extend(container::findings(&container::gather(std::path::Path::new("/"), &env)));
    findings.extend(rules::vulkan_half(&half, vk_layers, &env));
    findings.extend(rules::gpu(&vk, &config.config));
    findings.extend(rules::config(&config));
    findings.extend(rules::conflicts(&others, xr_layers, installed, &env));
    findings.extend(rules::eyes(gather::layer_log().as_deref()));
    Report { findings }
}

impl Report {
    pub fn count(&self, s: Status) -> usize {
        self.findings.iter().filter(|f| f.status == s).count()
    }

    /// 1 when any check is an error, else 0 (warnings do not fail).
    pub fn exit_code(&self) -> u8 {
        u8::from(self.count(Status::Error) > 0)
    }

    /// The aligned table: status word, check, detail, and the fix on the next line. `colour`:
    /// ANSI colours on the status word (only for a terminal).
    pub fn table(&self, colour: bool) -> String {
        let width = self.findings.iter().map(|f| f.check.chars().count()).max().unwrap_or(0);
        let mut out = String::new();
        for f in &self.findings {
            let word = format!("{:<7}", f.status.word());
            let word = match (colour, f.status) {
                (false, _) => word,
                (true, Status::Ok) => format!("\x1b[32m{word}\x1b[0m"),
                (true, Status::Warning) => format!("\x1b[33m{word}\x1b[0m"),
                (true, Status::Error) => format!("\x1b[31m{word}\x1b[0m"),
            };
            out.push_str(&format!("{word}  {:<width$}  {}\n", f.check, f.detail));
            if let Some(fix) = &f.fix {
                out.push_str(&format!("{:<7}  {:<width$}  fix: {fix}\n", "", ""));
            }
        }
        let (w, e) = (self.count(Status::Warning), self.count(Status::Error));
        out.push_str(&format!(
            "{} ok, {w} warning{}, {e} error{}\n",
            self.count(Status::Ok),
            if w == 1 { "" } else { "s" },
            if e == 1 { "" } else { "s" }
        ));
        out
    }

    /// The report as one JSON document.
    pub fn json(&self) -> String {
        let findings: Vec<serde_json::Value> = self
            .findings
            .iter()
            .map(|f| serde_json::json!({ "check": f.check, "status": f.status.word(), "detail": f.detail, "fix": f.fix }))
            .collect();
        let v = serde_json::json!({
            "findings": findings,
            "ok": self.count(Status::Ok),
            "warnings": self.count(Status::Warning),
            "errors": self.count(Status::Error),
            "exit_code": self.exit_code(),
        });
        serde_json::to_string_pretty(&v).unwrap_or_default() + "\n"
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report() -> Report {
        let f = |check: &str, status, fix: Option<&str>| Finding { check: check.into(), status, detail: format!("{check} detail"), fix: fix.map(str::to_string) };
        Report { findings: vec![f("a", Status::Ok, None), f("longer.check", Status::Warning, Some("do this")), f("b", Status::Error, Some("do that"))] }
    }

    #[test]
    fn table_is_aligned_and_plain_without_colour() {
        let t = report().table(false);
        let lines: Vec<&str> = t.lines().collect();
        assert_eq!(lines[0], "ok       a             a detail");
        assert_eq!(lines[1], "warning  longer.check  longer.check detail");
        assert_eq!(lines[2], "                       fix: do this");
        assert_eq!(lines[3], "error    b             b detail");
        assert_eq!(lines.last(), Some(&"1 ok, 1 warning, 1 error"));
        assert!(!t.contains('\x1b'));
        assert!(report().table(true).contains("\x1b[31merror"));
    }

    #[test]
    fn exit_code_counts_only_errors() {
        let mut r = report();
        assert_eq!(r.exit_code(), 1);
        r.findings.retain(|f| f.status != Status::Error);
        assert_eq!(r.exit_code(), 0, "warnings do not fail");
        let v: serde_json::Value = serde_json::from_str(&r.json()).unwrap();
        assert_eq!(v["warnings"], 1);
        assert_eq!(v["findings"][1]["fix"], "do this");
        assert_eq!(v["findings"][0]["fix"], serde_json::Value::Null);
    }
}
