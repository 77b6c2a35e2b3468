//! The upscale's GPU passes (`shaders/upscale_easu.comp`, `shaders/upscale_rcas.comp`): their
//! SPIR-V and push constants. Both read a sampled image with `texelFetch` (binding 0, combined
//! image sampler) and write an RGBA16F storage image (binding 1), read which tiles they skip from
//! a storage buffer (binding 2: `lens`, `upscale.skip_hidden`), one invocation per output pixel
//! in 16×16 workgroups; they match `filter::easu` and `filter::rcas` (tests/features/upscale_filters.rs
//! holds them to it on the device).

/// EASU's SPIR-V.
pub static EASU: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/upscale_easu.comp.spv"));
/// CAS with scaling (`upscale.method = cas`): EASU's interface, the third vector's x the
/// sharpness.
pub static CAS: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/upscale_cas.comp.spv"));
/// RCAS's SPIR-V.
pub static RCAS: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/upscale_rcas.comp.spv"));

/// RCAS writing 8-bit texels in the runtime image's encoding (sRGB, BGRA), copied into it.
pub static RCAS_RGBA8: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/upscale_rcas_rgba8.comp.spv"));
/// RCAS as a fragment pass into the runtime's image (the same filter, `upscale_rcas.glsl`).
pub static RCAS_FRAG: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/upscale_rcas.frag.spv"));
/// The bilinear upscale as a fragment pass.
pub static BILINEAR_FRAG: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/upscale_bilinear.frag.spv"));
/// The fragment passes' one full-viewport triangle.
pub static VERT: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/upscale.vert.spv"));

/// The workgroup's side in pixels (16×16: on the H100 RCAS ran in 0.034 ms per 2016×2240 eye
/// against 0.046 with 8×8, EASU alike; docs/benchmarks.md).
pub const GROUP: u32 = 16;

/// EASU's push constants: the source rect (texels of the sampled image) and the destination rect
/// (texels of the storage image), each x, y, width, height.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EasuParams {
    pub src_rect: [i32; 4],
    pub dst_rect: [i32; 4],
    /// Where EASU runs: an ellipse (centre x, y, radii) in destination texels, bilinear outside;
    /// radius 0: everywhere, negative: nowhere (the bilinear method).
    pub fovea: [f32; 4],
    /// `upscale.skip_hidden`: the job's first entry in the tile buffer (binding 2) and its tiles
    /// per row (0: nothing skipped).
    pub skip: [i32; 4],
}

/// RCAS's push constants: the rect (the same texels in both images) and the sharpness (x).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RcasParams {
    pub rect: [i32; 4],
    /// Sharpness; then, for the compute pass into 8-bit texels, sRGB-encode (1) and swap red
    /// and blue (1).
    pub sharpness: [f32; 4],
    /// Where RCAS sharpens (as `EasuParams::fovea`; radius 0: everywhere).
    pub fovea: [f32; 4],
    /// As `EasuParams::skip`.
    pub skip: [i32; 4],
}

impl EasuParams {
    /// The push constants' bytes (as the shader's std430-like block lays them out).
    pub fn bytes(&self) -> Vec<u8> {
        let ints = |v: &[i32; 4]| v.iter().flat_map(|x| x.to_ne_bytes()).collect::<Vec<u8>>();
        [ints(&self.src_rect), ints(&self.dst_rect), self.fovea.iter().flat_map(|v| v.to_ne_bytes()).collect(), ints(&self.skip)].concat()
    }
}

impl RcasParams {
    /// The push constants' bytes.
    pub fn bytes(&self) -> Vec<u8> {
        self.rect.iter().flat_map(|v| v.to_ne_bytes()).chain(self.sharpness.iter().chain(&self.fovea).flat_map(|v| v.to_ne_bytes())).chain(self.skip.iter().flat_map(|v| v.to_ne_bytes())).collect()
    }
}

/// The push constants' size (both passes).
pub const PUSH_BYTES: u32 = 64;

/// Workgroups covering `width`×`height` pixels.
pub fn groups(width: u32, height: u32) -> (u32, u32) {
    (width.div_ceil(GROUP), height.div_ceil(GROUP))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spirv_and_layouts() {
        for s in [EASU, RCAS] {
            assert_eq!(&s[..4], &0x0723_0203u32.to_le_bytes(), "SPIR-V magic");
        }
        assert_eq!(EasuParams::default().bytes().len(), std::mem::size_of::<EasuParams>());
        assert_eq!(EasuParams::default().bytes().len(), PUSH_BYTES as usize);
        assert_eq!(RcasParams::default().bytes().len(), PUSH_BYTES as usize);
        assert_eq!(RcasParams { sharpness: [0.5, 0.0, 0.0, 0.0], ..Default::default() }.bytes()[16..20], 0.5f32.to_ne_bytes());
        assert_eq!(groups(17, 8), (2, 1));
    }
}
