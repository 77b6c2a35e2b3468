//! Command-line options: which frame structure Bevy records, how heavy the scene is, how long
//! the app runs. Parsed by hand: clap would add to a build that is already long.

use bevy::prelude::Resource;

pub const USAGE: &str = "\
usage: bevy-scene [OPTIONS]

Frame structure (default: Bevy's defaults, MSAA 4x, no HDR, TonyMcMapface tonemapping):
  --msaa off|2|4|8     multisampling of the main pass (default 4)
  --hdr                render the main pass into an HDR (Rgba16Float) target, tonemapped after
  --bloom              Bevy's bloom (implies --hdr)
  --tonemapping NAME   none|reinhard|aces|agx|tony (default tony: Bevy's TonyMcMapface)
Scene:
  --lights N           N extra point lights over the ground (shadowless), for a heavy scene
Run:
  --frames N           ask the runtime to end the session after N frames (default: run until
                       the runtime ends it)
  --resolution WxH     swapchain size per eye (default: the runtime's recommended size)
  --help";

/// Bevy's tonemappers that need no extra feature (all of them with `tonemapping_luts`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tonemap {
    None,
    Reinhard,
    Aces,
    AgX,
    TonyMcMapface,
}

#[derive(Resource, Clone, Debug)]
pub struct Options {
    /// Sample count of the main pass; 1 is MSAA off.
    pub msaa: u32,
    pub hdr: bool,
    pub bloom: bool,
    pub tonemapping: Tonemap,
    pub lights: u32,
    pub frames: Option<u64>,
    pub resolution: Option<(u32, u32)>,
    pub help: bool,
}

impl Default for Options {
    fn default() -> Self {
        Options { msaa: 4, hdr: false, bloom: false, tonemapping: Tonemap::TonyMcMapface, lights: 0, frames: None, resolution: None, help: false }
    }
}

impl Options {
    pub fn parse(args: impl IntoIterator<Item = String>) -> Result<Options, String> {
        let mut o = Options::default();
        let mut args = args.into_iter();
        while let Some(arg) = args.next() {
            let mut value = |name: &str| args.next().ok_or_else(|| format!("{name} needs a value"));
            match arg.as_str() {
                "--msaa" => {
                    o.msaa = match value("--msaa")?.as_str() {
                        "off" | "1" => 1,
                        "2" => 2,
                        "4" => 4,
                        "8" => 8,
                        v => return Err(format!("--msaa {v}: want off, 2, 4 or 8")),
                    }
                }
                "--hdr" => o.hdr = true,
                "--bloom" => {
                    o.bloom = true;
                    o.hdr = true;
                }
                "--tonemapping" => {
                    o.tonemapping = match value("--tonemapping")?.as_str() {
                        "none" => Tonemap::None,
                        "reinhard" => Tonemap::Reinhard,
                        "aces" => Tonemap::Aces,
                        "agx" => Tonemap::AgX,
                        "tony" => Tonemap::TonyMcMapface,
                        v => return Err(format!("--tonemapping {v}: want none, reinhard, aces, agx or tony")),
                    }
                }
                "--lights" => o.lights = number(&value("--lights")?, "--lights")?,
                "--frames" => o.frames = Some(number(&value("--frames")?, "--frames")?).filter(|&n| n > 0),
                "--resolution" => {
                    let v = value("--resolution")?;
                    let (w, h) = v.split_once('x').ok_or_else(|| format!("--resolution {v}: want WxH"))?;
                    let (w, h): (u32, u32) = (number(w, "--resolution")?, number(h, "--resolution")?);
                    if w == 0 || h == 0 {
                        return Err(format!("--resolution {v}: empty"));
                    }
                    o.resolution = Some((w, h));
                }
                "--help" | "-h" => o.help = true,
                other => return Err(format!("unknown option {other:?}")),
            }
        }
        Ok(o)
    }
}

fn number<T: std::str::FromStr>(v: &str, name: &str) -> Result<T, String> {
    v.trim().parse().map_err(|_| format!("{name} {v:?}: not a number"))
}
