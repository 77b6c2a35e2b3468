//! Unit tests of the per-command-buffer state: recording, restoring and depth-test reading.
use super::super::resources::GraphicsPipeline;
use super::*;

fn vp(x: f32) -> Viewport {
    Viewport { x, y: 0.0, width: 100.0, height: 50.0, min_depth: 0.0, max_depth: 1.0 }
}

fn pipeline(dynamic: &[vk::DynamicState]) -> Arc<GraphicsPipeline> {
    Arc::new(GraphicsPipeline {
        handle: 9,
        render_pass: 1,
        subpass: 0,
        rendering: None,
        depth_test_enable: true,
        depth_write_enable: true,
        depth_compare_op: vk::CompareOp::LESS,
        dynamic_states: dynamic.to_vec(),
        parts: vk::GraphicsPipelineLibraryFlagsEXT::empty(),
        libraries: Vec::new(),
    })
}

#[test]
fn restore_replays_pipeline_then_dynamic_state() {
    let mut s = CmdState::default();
    s.begin(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
    s.bind_pipeline(9, Some(pipeline(&[vk::DynamicState::VIEWPORT, vk::DynamicState::SCISSOR, vk::DynamicState::DEPTH_COMPARE_OP])));
    s.record(StateCmd::SetViewport { first: 0, viewports: vec![vp(0.0)] });
    s.record(StateCmd::SetViewport { first: 1, viewports: vec![vp(100.0)] });
    s.record(StateCmd::SetScissor { first: 0, scissors: vec![Rect { x: 0, y: 0, width: 200, height: 50 }] });
    s.record(StateCmd::DepthCompareOp(vk::CompareOp::GREATER));
    s.record(StateCmd::DepthCompareOp(vk::CompareOp::GREATER_OR_EQUAL));
    assert_eq!(
        s.restore_commands(),
        vec![
            StateCmd::BindPipeline(9),
            StateCmd::SetViewport { first: 0, viewports: vec![vp(0.0), vp(100.0)] },
            StateCmd::SetScissor { first: 0, scissors: vec![Rect { x: 0, y: 0, width: 200, height: 50 }] },
            StateCmd::DepthCompareOp(vk::CompareOp::GREATER_OR_EQUAL),
        ]
    );
}

#[test]
fn binding_a_pipeline_drops_state_it_makes_static() {
    let mut s = CmdState::default();
    s.begin(vk::CommandBufferUsageFlags::empty());
    s.record(StateCmd::SetViewport { first: 0, viewports: vec![vp(1.0)] });
    s.record(StateCmd::LineWidth(2.0));
    s.record(StateCmd::BlendConstants([1.0; 4]));
    s.bind_pipeline(5, Some(pipeline(&[vk::DynamicState::BLEND_CONSTANTS])));
    assert_eq!(s.restore_commands(), vec![StateCmd::BindPipeline(5), StateCmd::BlendConstants([1.0; 4])]);
    // An untracked pipeline keeps everything set before it.
    s.record(StateCmd::LineWidth(3.0));
    s.bind_pipeline(6, None);
    assert_eq!(s.restore_commands().len(), 3);
}

#[test]
fn stencil_faces_merge_when_equal() {
    let mut s = CmdState::default();
    s.record(StateCmd::StencilReference { face: vk::StencilFaceFlags::FRONT_AND_BACK, reference: 3 });
    s.record(StateCmd::StencilWriteMask { face: vk::StencilFaceFlags::FRONT_AND_BACK, mask: 0xff });
    s.record(StateCmd::StencilWriteMask { face: vk::StencilFaceFlags::BACK, mask: 0x0f });
    let r = s.restore_commands();
    assert!(r.contains(&StateCmd::StencilReference { face: vk::StencilFaceFlags::FRONT_AND_BACK, reference: 3 }), "{r:?}");
    assert!(r.contains(&StateCmd::StencilWriteMask { face: vk::StencilFaceFlags::FRONT, mask: 0xff }), "{r:?}");
    assert!(r.contains(&StateCmd::StencilWriteMask { face: vk::StencilFaceFlags::BACK, mask: 0x0f }), "{r:?}");
    assert_eq!(r.len(), 3);
}

#[test]
fn with_count_and_gaps() {
    let mut s = CmdState::default();
    s.record(StateCmd::SetViewportWithCount(vec![vp(0.0), vp(1.0)]));
    s.record(StateCmd::SetViewport { first: 1, viewports: vec![vp(5.0)] });
    s.record(StateCmd::SetScissor { first: 0, scissors: vec![Rect::default()] });
    s.record(StateCmd::SetScissor { first: 2, scissors: vec![Rect { x: 1, ..Rect::default() }] });
    assert_eq!(
        s.restore_commands(),
        vec![
            StateCmd::SetViewportWithCount(vec![vp(0.0), vp(5.0)]),
            StateCmd::SetScissor { first: 0, scissors: vec![Rect::default()] },
            StateCmd::SetScissor { first: 2, scissors: vec![Rect { x: 1, ..Rect::default() }] },
        ]
    );
}

#[test]
fn push_constants_replay_in_order_and_collapse() {
    let mut s = CmdState::default();
    let push = |offset: u32, data: Vec<u8>| StateCmd::PushConstants { layout: 1, stages: vk::ShaderStageFlags::VERTEX, offset, data };
    s.record(push(0, vec![1; 4]));
    s.record(push(4, vec![2; 4]));
    s.record(push(0, vec![3; 16]));
    s.record(push(8, vec![4; 4]));
    assert_eq!(s.restore_commands(), vec![push(0, vec![3; 16]), push(8, vec![4; 4])]);
}

#[test]
fn begin_reset_and_execute_commands_clear_state() {
    let mut s = CmdState::default();
    s.record(StateCmd::CullMode(vk::CullModeFlags::BACK));
    s.begin(vk::CommandBufferUsageFlags::empty());
    assert!(s.restore_commands().is_empty() && s.recording);
    s.record(StateCmd::CullMode(vk::CullModeFlags::BACK));
    s.bind_pipeline(3, None);
    s.forget_graphics_state();
    assert!(s.restore_commands().is_empty() && s.recording);
    s.reset();
    assert!(!s.recording);
}

#[test]
fn every_dynamic_state_command_maps_to_its_enum() {
    let f = vk::StencilFaceFlags::FRONT;
    let all = [
        StateCmd::LineWidth(1.0),
        StateCmd::DepthBias { constant_factor: 1.0, clamp: 0.0, slope_factor: 1.0 },
        StateCmd::DepthBounds { min: 0.0, max: 1.0 },
        StateCmd::StencilCompareMask { face: f, mask: 1 },
        StateCmd::FrontFace(vk::FrontFace::CLOCKWISE),
        StateCmd::PrimitiveTopology(vk::PrimitiveTopology::TRIANGLE_LIST),
        StateCmd::DepthTestEnable(true),
        StateCmd::DepthWriteEnable(true),
        StateCmd::DepthBoundsTestEnable(false),
        StateCmd::StencilTestEnable(false),
        StateCmd::StencilOp {
            face: f,
            fail_op: vk::StencilOp::KEEP,
            pass_op: vk::StencilOp::KEEP,
            depth_fail_op: vk::StencilOp::KEEP,
            compare_op: vk::CompareOp::ALWAYS,
        },
        StateCmd::RasterizerDiscardEnable(false),
        StateCmd::DepthBiasEnable(false),
        StateCmd::PrimitiveRestartEnable(false),
        StateCmd::LineStipple { factor: 1, pattern: 0xffff },
        StateCmd::ColorWriteEnable(vec![true]),
        StateCmd::LogicOp(vk::LogicOp::COPY),
        StateCmd::PatchControlPoints(3),
    ];
    let mut s = CmdState::default();
    for c in &all {
        s.record(c.clone());
    }
    // Every one survives (no pipeline bound) and replays exactly once.
    assert_eq!(s.restore_commands().len(), all.len());
    let mut kinds: Vec<i32> = all.iter().map(|c| c.dynamic_state().unwrap().as_raw()).collect();
    kinds.dedup();
    assert_eq!(kinds.len(), all.len());
}

#[test]
fn vertex_buffers_replay_in_runs_and_survive_pipeline_binds() {
    let mut s = CmdState::default();
    let b = |buffer, v2, stride| VertexBinding { buffer, offset: 0, size: None, stride, v2 };
    s.record(StateCmd::BindVertexBuffers { first: 0, bindings: vec![b(1, false, None), b(2, false, None)] });
    s.record(StateCmd::BindVertexBuffers { first: 2, bindings: vec![b(3, true, Some(16))] });
    s.record(StateCmd::BindVertexBuffers { first: 5, bindings: vec![b(4, false, None)] });
    s.bind_pipeline(7, Some(pipeline(&[])));
    assert!(s.has_vertex_buffers());
    assert_eq!(
        s.restore_commands(),
        vec![
            StateCmd::BindPipeline(7),
            StateCmd::BindVertexBuffers { first: 0, bindings: vec![b(1, false, None), b(2, false, None)] },
            StateCmd::BindVertexBuffers { first: 2, bindings: vec![b(3, true, Some(16))] },
            StateCmd::BindVertexBuffers { first: 5, bindings: vec![b(4, false, None)] },
        ]
    );
    s.forget_graphics_state();
    assert!(!s.has_vertex_buffers());
}

#[test]
fn clear_value_readings() {
    let c = ClearValue([0.5f32.to_bits(), 7, 0, 0]);
    assert_eq!((c.depth(), c.stencil()), (0.5, 7));
    assert_eq!(c.color_f32()[0], 0.5);
}

#[test]
fn descriptor_sets_are_kept_in_order_and_covered_binds_dropped() {
    let mut s = CmdState::default();
    let bind = |first: u32, sets: &[u64]| StateCmd::BindDescriptorSets { layout: 7, first, sets: sets.to_vec(), dynamic_offsets: vec![] };
    s.record(bind(0, &[1, 2]));
    s.record(bind(1, &[3]));
    assert_eq!(s.descriptor_set_commands(), vec![bind(0, &[1, 2]), bind(1, &[3])]);
    s.record(bind(0, &[4, 5]));
    assert_eq!(s.descriptor_set_commands(), vec![bind(0, &[4, 5])], "both earlier binds are covered");
    assert!(s.restore_commands().is_empty(), "sets are restored only on request");
    s.bind_pipeline(9, None);
    assert_eq!(s.descriptor_set_commands().len(), 1, "binding a pipeline keeps the sets");
    s.forget_graphics_state();
    assert!(s.descriptor_set_commands().is_empty());
}

#[test]
fn extended_dynamic_state_3_and_vertex_input_are_restored_per_attachment() {
    use crate::track::ext_state::{ExtState, VertexInputAttribute, VertexInputBinding};
    let mut s = CmdState::default();
    s.begin(vk::CommandBufferUsageFlags::empty());
    let blend = |attachment, enable| StateCmd::Ext(ExtState::ColorBlendEnable { attachment, enable });
    let mask = |attachment| StateCmd::Ext(ExtState::ColorWriteMask { attachment, mask: vk::ColorComponentFlags::RGBA });
    let input = StateCmd::Ext(ExtState::VertexInput {
        bindings: vec![VertexInputBinding { binding: 0, stride: 40, input_rate: vk::VertexInputRate::VERTEX, divisor: 1 }],
        attributes: vec![VertexInputAttribute { location: 0, binding: 0, format: vk::Format::R32G32B32_SFLOAT, offset: 0 }],
    });
    // Set before a pipeline that has it static: that pipeline's bind overwrites it.
    s.record(StateCmd::Ext(ExtState::DepthClampEnable(true)));
    s.bind_pipeline(
        3,
        Some(pipeline(&[
            vk::DynamicState::COLOR_BLEND_ENABLE_EXT,
            vk::DynamicState::COLOR_WRITE_MASK_EXT,
            vk::DynamicState::POLYGON_MODE_EXT,
            vk::DynamicState::VERTEX_INPUT_EXT,
        ])),
    );
    for c in [blend(0, true), blend(1, false), mask(0), mask(1), StateCmd::Ext(ExtState::PolygonMode(vk::PolygonMode::FILL)), input.clone()] {
        s.record(c);
    }
    // A later command for attachment 1 only replaces attachment 1's value.
    s.record(blend(1, true));
    let restore = s.restore_commands();
    assert_eq!(restore[0], StateCmd::BindPipeline(3));
    assert!(restore.contains(&blend(0, true)) && restore.contains(&blend(1, true)) && !restore.contains(&blend(1, false)));
    assert!(restore.contains(&mask(0)) && restore.contains(&mask(1)) && restore.contains(&input));
    assert_eq!(restore.len(), 7, "pipeline, 2 blend enables, 2 write masks, polygon mode, vertex input: {restore:?}");
    // Binding a pipeline that makes them static drops them.
    s.bind_pipeline(4, Some(pipeline(&[vk::DynamicState::POLYGON_MODE_EXT])));
    assert_eq!(s.restore_commands(), vec![StateCmd::BindPipeline(4), StateCmd::Ext(ExtState::PolygonMode(vk::PolygonMode::FILL))]);
}

#[test]
fn shader_objects_are_rebound_with_every_state() {
    let mut s = CmdState::default();
    s.begin(vk::CommandBufferUsageFlags::empty());
    s.bind_pipeline(9, Some(pipeline(&[])));
    let (v, t, f) = (vk::ShaderStageFlags::VERTEX, vk::ShaderStageFlags::TESSELLATION_CONTROL, vk::ShaderStageFlags::FRAGMENT);
    s.record(StateCmd::BindShaders { stages: vec![v, t, f], shaders: vec![11, 0, 12] });
    s.record(StateCmd::DepthTestEnable(true));
    // Set before the pipeline of an earlier draw would have made it static: with shader objects
    // every state is the command buffer's.
    s.record(StateCmd::LineWidth(1.0));
    assert_eq!(s.depth_tested(), None, "the compare op is not set yet");
    s.record(StateCmd::DepthCompareOp(vk::CompareOp::GREATER));
    assert_eq!(s.depth_tested(), Some(true));
    // The fragment shader replaced: one slot per stage, in the order first bound.
    s.record(StateCmd::BindShaders { stages: vec![f], shaders: vec![13] });
    let restore = s.restore_commands();
    assert_eq!(restore[0], StateCmd::BindShaders { stages: vec![v, t, f], shaders: vec![11, 0, 13] });
    assert_eq!(restore.len(), 4);
    // A pipeline bound afterwards unbinds them: it is what is restored then.
    s.bind_pipeline(9, Some(pipeline(&[])));
    assert_eq!(s.restore_commands(), vec![StateCmd::BindPipeline(9)]);
    assert_eq!(s.depth_tested(), Some(true), "the pipeline's own depth test");
}

#[test]
fn a_compute_shader_object_is_the_compute_bind_points() {
    let mut s = CmdState::default();
    s.begin(vk::CommandBufferUsageFlags::empty());
    s.compute.pipeline = Some(5);
    s.record(StateCmd::BindShaders { stages: vec![vk::ShaderStageFlags::COMPUTE], shaders: vec![21] });
    assert_eq!(s.compute.shader, Some(21));
    // Graphics are untouched: no shader objects there, nothing to restore.
    assert!(s.restore_commands().is_empty());
    assert_eq!(s.depth_tested(), None);
}
