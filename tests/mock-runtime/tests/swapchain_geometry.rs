//! Swapchains beyond one sample and one level: multisampled colour swapchains (rendered with a
//! sample mask, so only a real resolve captures the expected colour), mip chains (captured from
//! level 0, every level kept in its attachment layout), and what `xrCreateSwapchain` refuses:
//! sample counts the device lacks, mip counts beyond the full chain, multisampled depth,
//! multisampled mip chains and cube swapchains.

mod common;

use ash::vk;
use common::*;
use openxr_sys as xr;
use xr::pfn;

/// Compiles GLSL with glslangValidator (the workspace's shader compiler, which xr-scene's build
/// also needs) into SPIR-V words.
fn spirv(name: &str, source: &str) -> Vec<u32> {
    let dir = std::env::temp_dir().join(format!("mock-runtime-test-{}", std::process::id())).join("shaders");
    std::fs::create_dir_all(&dir).unwrap();
    let src = dir.join(name);
    let out = dir.join(format!("{name}.spv"));
    std::fs::write(&src, source).unwrap();
    let status = std::process::Command::new("glslangValidator")
        .args(["-V", "--target-env", "vulkan1.0", "-o"])
        .arg(&out)
        .arg(&src)
        .stdout(std::process::Stdio::null())
        .status()
        .expect("glslangValidator (package glslang-tools) is needed to build this test's shaders");
    assert!(status.success(), "glslangValidator failed on {name}");
    ash::util::read_spv(&mut std::io::Cursor::new(std::fs::read(&out).unwrap())).unwrap()
}

/// One full-screen triangle, one constant colour.
const VERT: &str = "#version 450\nvoid main() {\n  vec2 p = vec2((gl_VertexIndex << 1) & 2, gl_VertexIndex & 2);\n  gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);\n}\n";
const FRAG: &str = "#version 450\nlayout(location = 0) out vec4 color;\nvoid main() { color = vec4(1.0, 0.0, 0.0, 1.0); }\n";

fn decode(path: &std::path::Path) -> (u32, u32, Vec<[u8; 3]>) {
    let dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))));
    let mut r = dec.read_info().unwrap();
    let mut buf = vec![0; r.output_buffer_size().unwrap()];
    let info = r.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    (info.width, info.height, buf[..info.buffer_size()].chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect())
}

fn destroy_swapchain(x: &Xr, sc: xr::Swapchain) {
    let f: pfn::DestroySwapchain = x.f("xrDestroySwapchain");
    // SAFETY: a swapchain of this instance, not in use.
    assert_eq!(unsafe { f(sc) }, xr::Result::SUCCESS);
}

/// Sample counts the device offers for a colour swapchain of `format` as the mock creates it
/// (the app's usage plus TRANSFER_SRC and COLOR_ATTACHMENT).
fn device_sample_counts(gfx: &Gfx, format: vk::Format) -> vk::SampleCountFlags {
    let usage = vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::TRANSFER_DST | vk::ImageUsageFlags::TRANSFER_SRC;
    // SAFETY: valid physical device; plain query.
    unsafe { gfx.instance.get_physical_device_image_format_properties(gfx.phys, format, vk::ImageType::TYPE_2D, vk::ImageTiling::OPTIMAL, usage, vk::ImageCreateFlags::empty()) }
        .map(|p| p.sample_counts)
        .unwrap_or(vk::SampleCountFlags::TYPE_1)
}

#[test]
fn refused_geometries() {
    let _g = serial();
    let fx = fixture(&["XR_KHR_vulkan_enable2"]);
    let (x, s) = (fx.xr(), fx.session);
    let color = |f: &dyn Fn(&mut xr::SwapchainCreateInfo)| {
        let mut ci = swapchain_info(vk::Format::R8G8B8A8_UNORM, 64, 32, 1);
        f(&mut ci);
        try_create_swapchain(x, s, &ci)
    };
    // Every Vulkan sample count: accepted exactly where the device supports it.
    let supported = device_sample_counts(&fx.gfx, vk::Format::R8G8B8A8_UNORM);
    assert!(supported.as_raw() > 1, "the device offers no MSAA for R8G8B8A8_UNORM: {supported:?}");
    for n in [1, 2, 4, 8, 16, 32, 64] {
        let r = color(&|ci| ci.sample_count = n);
        let want = supported.contains(vk::SampleCountFlags::from_raw(n));
        assert_eq!(r.is_ok(), want, "sampleCount {n} (device: {supported:?}): {r:?}");
        match r {
            Ok(sc) => destroy_swapchain(x, sc),
            Err(e) => assert_eq!(e, xr::Result::ERROR_VALIDATION_FAILURE, "sampleCount {n}"),
        }
    }
    for n in [0, 3, 6, 128] {
        assert_eq!(color(&|ci| ci.sample_count = n).err(), Some(xr::Result::ERROR_VALIDATION_FAILURE), "sampleCount {n}");
    }
    let msaa = (1..=6).map(|b| 1u32 << b).find(|n| supported.contains(vk::SampleCountFlags::from_raw(*n))).unwrap();
    // A multisampled Vulkan image has one level; multisampled depth is not resolved by capture.
    assert_eq!(color(&|ci| {
        ci.sample_count = msaa;
        ci.mip_count = 2;
    }).err(), Some(xr::Result::ERROR_VALIDATION_FAILURE));
    let mut depth = swapchain_info(vk::Format::D32_SFLOAT, 64, 32, 1);
    depth.sample_count = msaa;
    assert_eq!(try_create_swapchain(x, s, &depth).err(), Some(xr::Result::ERROR_VALIDATION_FAILURE));
    // Mip counts: 1..=7 for 64×32 (64, 32, 16, 8, 4, 2, 1).
    for m in 1..=7 {
        let sc = color(&|ci| ci.mip_count = m).unwrap_or_else(|e| panic!("mipCount {m}: {e:?}"));
        destroy_swapchain(x, sc);
    }
    for m in [0, 8, 100] {
        assert_eq!(color(&|ci| ci.mip_count = m).err(), Some(xr::Result::ERROR_VALIDATION_FAILURE), "mipCount {m}");
    }
    depth.sample_count = 1;
    depth.mip_count = 3;
    let sc = try_create_swapchain(x, s, &depth).expect("a depth mip chain");
    destroy_swapchain(x, sc);
    // Cube swapchains (and any faceCount but 1) stay refused.
    for f in [0, 2, 6] {
        assert_eq!(color(&|ci| ci.face_count = f).err(), Some(xr::Result::ERROR_VALIDATION_FAILURE), "faceCount {f}");
    }
}

/// The Vulkan objects of the MSAA test's two passes: layer 0 gets a draw that covers only half of
/// each pixel's samples (sample mask 0b0011 of 4, or the lower half of N) over a blue clear, layer
/// 1 only a green clear.
struct MsaaPasses {
    render_pass: vk::RenderPass,
    layout: vk::PipelineLayout,
    pipeline: vk::Pipeline,
    views: Vec<vk::ImageView>,
    framebuffers: Vec<vk::Framebuffer>,
}

impl MsaaPasses {
    fn new(d: &ash::Device, image: vk::Image, format: vk::Format, samples: vk::SampleCountFlags, extent: vk::Extent2D) -> MsaaPasses {
        // SAFETY: plain object creation on a live device; destroyed in `destroy`.
        unsafe {
            let att = [vk::AttachmentDescription::default()
                .format(format)
                .samples(samples)
                .load_op(vk::AttachmentLoadOp::CLEAR)
                .store_op(vk::AttachmentStoreOp::STORE)
                .stencil_load_op(vk::AttachmentLoadOp::DONT_CARE)
                .stencil_store_op(vk::AttachmentStoreOp::DONT_CARE)
                .initial_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)
                .final_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)];
            let refs = [vk::AttachmentReference { attachment: 0, layout: vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL }];
            let sub = [vk::SubpassDescription::default().pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS).color_attachments(&refs)];
            let render_pass = d.create_render_pass(&vk::RenderPassCreateInfo::default().attachments(&att).subpasses(&sub), None).unwrap();
            let mut views = Vec::new();
            let mut framebuffers = Vec::new();
            for layer in 0..2 {
                let v = d
                    .create_image_view(
                        &vk::ImageViewCreateInfo::default()
                            .image(image)
                            .view_type(vk::ImageViewType::TYPE_2D)
                            .format(format)
                            .subresource_range(vk::ImageSubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: 1, base_array_layer: layer, layer_count: 1 }),
                        None,
                    )
                    .unwrap();
                views.push(v);
                let a = [v];
                framebuffers.push(
                    d.create_framebuffer(&vk::FramebufferCreateInfo::default().render_pass(render_pass).attachments(&a).width(extent.width).height(extent.height).layers(1), None)
                        .unwrap(),
                );
            }
            let layout = d.create_pipeline_layout(&vk::PipelineLayoutCreateInfo::default(), None).unwrap();
            let (vs, fs) = (spirv("msaa.vert", VERT), spirv("msaa.frag", FRAG));
            let vert = d.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&vs), None).unwrap();
            let frag = d.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&fs), None).unwrap();
            let stages = [
                vk::PipelineShaderStageCreateInfo::default().stage(vk::ShaderStageFlags::VERTEX).module(vert).name(c"main"),
                vk::PipelineShaderStageCreateInfo::default().stage(vk::ShaderStageFlags::FRAGMENT).module(frag).name(c"main"),
            ];
            let vertex_input = vk::PipelineVertexInputStateCreateInfo::default();
            let assembly = vk::PipelineInputAssemblyStateCreateInfo::default().topology(vk::PrimitiveTopology::TRIANGLE_LIST);
            let viewport = vk::PipelineViewportStateCreateInfo::default().viewport_count(1).scissor_count(1);
            let raster = vk::PipelineRasterizationStateCreateInfo::default().polygon_mode(vk::PolygonMode::FILL).cull_mode(vk::CullModeFlags::NONE).line_width(1.0);
            // Half of the samples: a capture that read one sample would see red or blue, only a
            // resolve sees their average.
            assert!((2..=32).contains(&samples.as_raw()), "one sample-mask word: {samples:?}");
            let mask = [(1u32 << (samples.as_raw() / 2)) - 1];
            let multisample = vk::PipelineMultisampleStateCreateInfo::default().rasterization_samples(samples).sample_mask(&mask);
            let blend_att = [vk::PipelineColorBlendAttachmentState::default().color_write_mask(vk::ColorComponentFlags::RGBA)];
            let blend = vk::PipelineColorBlendStateCreateInfo::default().attachments(&blend_att);
            let dynamic_states = [vk::DynamicState::VIEWPORT, vk::DynamicState::SCISSOR];
            let dynamic = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dynamic_states);
            let info = vk::GraphicsPipelineCreateInfo::default()
                .stages(&stages)
                .vertex_input_state(&vertex_input)
                .input_assembly_state(&assembly)
                .viewport_state(&viewport)
                .rasterization_state(&raster)
                .multisample_state(&multisample)
                .color_blend_state(&blend)
                .dynamic_state(&dynamic)
                .layout(layout)
                .render_pass(render_pass)
                .subpass(0);
            let pipeline = d.create_graphics_pipelines(vk::PipelineCache::null(), &[info], None).unwrap()[0];
            d.destroy_shader_module(vert, None);
            d.destroy_shader_module(frag, None);
            MsaaPasses { render_pass, layout, pipeline, views, framebuffers }
        }
    }

    /// Layer 0: blue clear, then the half-sample red draw over the left half (x < width / 2);
    /// layer 1: green clear.
    fn record(&self, d: &ash::Device, cb: vk::CommandBuffer, extent: vk::Extent2D) {
        let clear = |rgba: [f32; 4]| [vk::ClearValue { color: vk::ClearColorValue { float32: rgba } }];
        let area = vk::Rect2D { offset: vk::Offset2D::default(), extent };
        let half = vk::Extent2D { width: extent.width / 2, height: extent.height };
        // SAFETY: recording into a fresh command buffer; the image is in COLOR_ATTACHMENT_OPTIMAL
        // as the runtime hands it out.
        unsafe {
            for (layer, rgba) in [(0, [0.0, 0.0, 1.0, 1.0]), (1, [0.0, 1.0, 0.0, 1.0])] {
                let c = clear(rgba);
                let begin = vk::RenderPassBeginInfo::default().render_pass(self.render_pass).framebuffer(self.framebuffers[layer]).render_area(area).clear_values(&c);
                d.cmd_begin_render_pass(cb, &begin, vk::SubpassContents::INLINE);
                if layer == 0 {
                    d.cmd_bind_pipeline(cb, vk::PipelineBindPoint::GRAPHICS, self.pipeline);
                    d.cmd_set_viewport(cb, 0, &[vk::Viewport { x: 0.0, y: 0.0, width: half.width as f32, height: half.height as f32, min_depth: 0.0, max_depth: 1.0 }]);
                    d.cmd_set_scissor(cb, 0, &[vk::Rect2D { offset: vk::Offset2D::default(), extent: half }]);
                    d.cmd_draw(cb, 3, 1, 0, 0);
                }
                d.cmd_end_render_pass(cb);
            }
        }
    }

    fn destroy(&self, d: &ash::Device) {
        // SAFETY: the queue is idle (every submission was waited for).
        unsafe {
            d.destroy_pipeline(self.pipeline, None);
            d.destroy_pipeline_layout(self.layout, None);
            self.framebuffers.iter().for_each(|f| d.destroy_framebuffer(*f, None));
            self.views.iter().for_each(|v| d.destroy_image_view(*v, None));
            d.destroy_render_pass(self.render_pass, None);
        }
    }
}

/// An MSAA swapchain (2 layers) rendered by the app and captured: the PNG is the resolved picture
/// of the submitted rect of the submitted layer, half-covered pixels their samples' average.
#[test]
fn msaa_swapchain_is_captured_resolved() {
    let _g = serial();
    let dir = scratch_dir("capture-msaa");
    std::env::set_var("MOCK_XR_CAPTURE", &dir);
    let errors_before = VALIDATION_ERRORS.load(std::sync::atomic::Ordering::SeqCst);
    let fx = fixture(&["XR_KHR_vulkan_enable2"]);
    let (x, s) = (fx.xr(), fx.session);
    let format = vk::Format::R8G8B8A8_UNORM;
    let supported = device_sample_counts(&fx.gfx, format);
    // 4 where the device has it (every Vulkan device with MSAA does), else its smallest count.
    let n = if supported.contains(vk::SampleCountFlags::TYPE_4) { 4 } else { (1..=6).map(|b| 1u32 << b).find(|n| supported.contains(vk::SampleCountFlags::from_raw(*n))).expect("MSAA") };
    let samples = vk::SampleCountFlags::from_raw(n);
    let stage = reference_space(x, s, xr::ReferenceSpaceType::STAGE);
    let mut ci = swapchain_info(format, 64, 32, 2);
    ci.sample_count = n;
    ci.usage_flags = xr::SwapchainUsageFlags::COLOR_ATTACHMENT;
    let sc = try_create_swapchain(x, s, &ci).expect("MSAA swapchain");
    let images = swapchain_images(x, sc);
    let extent = vk::Extent2D { width: 64, height: 32 };
    let d = &fx.gfx.device;
    assert_eq!(begin_session(x, s), xr::Result::SUCCESS);
    let (r, st) = wait_frame(x, s);
    assert_eq!(r, xr::Result::SUCCESS);
    assert_eq!(begin_frame(x, s), xr::Result::SUCCESS);
    let i = acquire_wait(x, sc);
    let passes = MsaaPasses::new(d, images[i as usize], format, samples, extent);
    fx.gfx.run(|cb| passes.record(d, cb, extent));
    assert_eq!(release(x, sc), xr::Result::SUCCESS);
    // View 0: x 16..48 of layer 0 (half drawn, half clear); view 1: a rect inside layer 1.
    let mut views = [projection_view(sc, 16, 32, 32, 0), projection_view(sc, 8, 32, 16, 1)];
    views[1].sub_image.image_rect.offset.y = 8;
    let layer = projection_layer(stage, &views);
    assert_eq!(end_frame(x, s, st.predicted_display_time, &[&layer as *const _ as *const _]), xr::Result::SUCCESS);
    passes.destroy(d);

    let (w, h, px) = decode(&dir.join("frame-00000-view-0.png"));
    assert_eq!((w, h), (32, 32));
    for (k, p) in px.iter().enumerate() {
        let x = k as u32 % w;
        // Half of the samples red, half blue: 127.5 each, as the resolve rounds it.
        let want = if x < 16 { [128, 0, 128] } else { [0, 0, 255] };
        assert!(p.iter().zip(want).all(|(a, b)| a.abs_diff(b) <= 1), "view 0 pixel ({x}, {}): {p:?}, want {want:?}", k as u32 / w);
    }
    let (w, h, px) = decode(&dir.join("frame-00000-view-1.png"));
    assert_eq!((w, h), (32, 16));
    assert!(px.iter().all(|p| *p == [0, 255, 0]), "layer 1 is green: {:?}", &px[..4]);
    destroy_swapchain(x, sc);
    drop(fx);
    assert_eq!(VALIDATION_ERRORS.load(std::sync::atomic::Ordering::SeqCst), errors_before, "Vulkan validation errors");
}

/// Clears every level of layer 0 (level 0 to `top`, the others to `rest`) and hands the image
/// back in COLOR_ATTACHMENT_OPTIMAL: an app that fills its own mip chain.
fn clear_levels(gfx: &Gfx, image: vk::Image, levels: u32, top: [f32; 4], rest: [f32; 4]) {
    let all = vk::ImageSubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: levels, base_array_layer: 0, layer_count: 1 };
    let barrier = |old, new, src, dst| {
        vk::ImageMemoryBarrier::default()
            .src_access_mask(src)
            .dst_access_mask(dst)
            .old_layout(old)
            .new_layout(new)
            .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .image(image)
            .subresource_range(all)
    };
    type L = vk::ImageLayout;
    type A = vk::AccessFlags;
    type S = vk::PipelineStageFlags;
    gfx.run(|cb| {
        let d = &gfx.device;
        // SAFETY: recording into the helper's command buffer; the runtime hands every level out
        // in COLOR_ATTACHMENT_OPTIMAL.
        unsafe {
            let to = barrier(L::COLOR_ATTACHMENT_OPTIMAL, L::TRANSFER_DST_OPTIMAL, A::COLOR_ATTACHMENT_WRITE, A::TRANSFER_WRITE);
            d.cmd_pipeline_barrier(cb, S::COLOR_ATTACHMENT_OUTPUT | S::TRANSFER, S::TRANSFER, vk::DependencyFlags::empty(), &[], &[], &[to]);
            let top_range = vk::ImageSubresourceRange { level_count: 1, ..all };
            let rest_range = vk::ImageSubresourceRange { base_mip_level: 1, level_count: levels - 1, ..all };
            d.cmd_clear_color_image(cb, image, L::TRANSFER_DST_OPTIMAL, &vk::ClearColorValue { float32: top }, &[top_range]);
            d.cmd_clear_color_image(cb, image, L::TRANSFER_DST_OPTIMAL, &vk::ClearColorValue { float32: rest }, &[rest_range]);
            let back = barrier(L::TRANSFER_DST_OPTIMAL, L::COLOR_ATTACHMENT_OPTIMAL, A::TRANSFER_WRITE, A::COLOR_ATTACHMENT_READ | A::COLOR_ATTACHMENT_WRITE);
            d.cmd_pipeline_barrier(cb, S::TRANSFER, S::COLOR_ATTACHMENT_OUTPUT, vk::DependencyFlags::empty(), &[], &[], &[back]);
        }
    });
}

/// A 3-level swapchain: each frame's capture is level 0, whatever the other levels hold, and the
/// capture leaves every level in COLOR_ATTACHMENT_OPTIMAL (the images come round again after
/// three frames, and validation checks the layouts the app's barriers name).
#[test]
fn mip_chain_is_captured_from_level_0() {
    let _g = serial();
    let dir = scratch_dir("capture-mips");
    std::env::set_var("MOCK_XR_CAPTURE", &dir);
    let errors_before = VALIDATION_ERRORS.load(std::sync::atomic::Ordering::SeqCst);
    let fx = fixture(&["XR_KHR_vulkan_enable2"]);
    let (x, s) = (fx.xr(), fx.session);
    let stage = reference_space(x, s, xr::ReferenceSpaceType::STAGE);
    let mut ci = swapchain_info(vk::Format::R8G8B8A8_UNORM, 64, 32, 1);
    ci.mip_count = 3;
    let sc = try_create_swapchain(x, s, &ci).expect("mip chain swapchain");
    let images = swapchain_images(x, sc);
    assert_eq!(begin_session(x, s), xr::Result::SUCCESS);
    let colours: [([f32; 4], [u8; 3]); 5] = [
        ([1.0, 0.0, 0.0, 1.0], [255, 0, 0]),
        ([0.0, 1.0, 0.0, 1.0], [0, 255, 0]),
        ([0.0, 0.0, 1.0, 1.0], [0, 0, 255]),
        ([1.0, 1.0, 0.0, 1.0], [255, 255, 0]),
        ([0.0, 1.0, 1.0, 1.0], [0, 255, 255]),
    ];
    for (top, _) in colours {
        let (r, st) = wait_frame(x, s);
        assert_eq!(r, xr::Result::SUCCESS);
        assert_eq!(begin_frame(x, s), xr::Result::SUCCESS);
        let i = acquire_wait(x, sc);
        clear_levels(&fx.gfx, images[i as usize], 3, top, [1.0, 1.0, 1.0, 1.0]);
        assert_eq!(release(x, sc), xr::Result::SUCCESS);
        let views = [projection_view(sc, 0, 32, 32, 0), projection_view(sc, 32, 32, 32, 0)];
        let layer = projection_layer(stage, &views);
        assert_eq!(end_frame(x, s, st.predicted_display_time, &[&layer as *const _ as *const _]), xr::Result::SUCCESS);
    }
    for (frame, (_, rgb)) in colours.iter().enumerate() {
        for view in 0..2 {
            let (w, h, px) = decode(&dir.join(format!("frame-{frame:05}-view-{view}.png")));
            assert_eq!((w, h), (32, 32));
            assert!(px.iter().all(|p| p == rgb), "frame {frame} view {view}: {:?}, want {rgb:?}", px[0]);
        }
    }
    destroy_swapchain(x, sc);
    drop(fx);
    assert_eq!(VALIDATION_ERRORS.load(std::sync::atomic::Ordering::SeqCst), errors_before, "Vulkan validation errors");
}
