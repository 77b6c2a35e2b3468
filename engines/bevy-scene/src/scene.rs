//! The scene: a ground plane, objects from arm's length out to 200 m (the far ones are what a far
//! field can reuse), a sun and a lamp with shadows, optionally many shadowless point lights. All
//! of it placed by constants; the head is where the runtime says (STAGE space: the mock runtime's
//! head stands at (0, 1.6, 0) looking down −Z, Monado's simulated one close to it).

use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::post_process::bloom::Bloom;
use bevy::prelude::*;
use bevy::camera::Hdr;
use bevy_mod_xr::camera::XrCamera;

use crate::options::{Options, Tonemap};

/// The clear colour: what the views show above the horizon.
pub const SKY: Color = Color::srgb(0.45, 0.62, 0.85);

/// (position, size, colour) of the boxes: near ones in reach, mid ones, far ones 60–200 m away.
const BOXES: &[([f32; 3], [f32; 3], [u8; 3])] = &[
    ([-0.9, 0.4, -2.5], [0.8, 0.8, 0.8], [200, 60, 50]),
    ([1.1, 0.25, -3.0], [0.5, 0.5, 0.5], [60, 170, 80]),
    ([-4.0, 1.0, -10.0], [2.0, 2.0, 2.0], [220, 180, 40]),
    ([6.0, 1.5, -18.0], [3.0, 3.0, 3.0], [120, 80, 200]),
    ([-25.0, 6.0, -70.0], [12.0, 12.0, 12.0], [180, 100, 60]),
    ([40.0, 15.0, -150.0], [30.0, 30.0, 30.0], [90, 110, 140]),
    ([-10.0, 25.0, -200.0], [60.0, 50.0, 20.0], [140, 140, 150]),
];

/// (centre, radius, colour) of the spheres.
const SPHERES: &[([f32; 3], f32, [u8; 3])] = &[
    ([0.2, 1.3, -4.0], 0.5, [230, 230, 230]),
    ([3.0, 2.0, -30.0], 2.0, [200, 90, 150]),
    ([15.0, 8.0, -90.0], 8.0, [70, 160, 170]),
    ([-60.0, 20.0, -180.0], 20.0, [210, 200, 120]),
];

pub fn setup(mut commands: Commands, mut meshes: ResMut<Assets<Mesh>>, mut materials: ResMut<Assets<StandardMaterial>>, options: Res<Options>) {
    let mut material = |rgb: [u8; 3], roughness: f32| {
        materials.add(StandardMaterial { base_color: Color::srgb_u8(rgb[0], rgb[1], rgb[2]), perceptual_roughness: roughness, ..default() })
    };
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::default().mesh().size(500.0, 500.0))),
        MeshMaterial3d(material([110, 120, 95], 0.95)),
        Transform::IDENTITY,
    ));
    for &(pos, size, rgb) in BOXES {
        commands.spawn((
            Mesh3d(meshes.add(Cuboid::new(size[0], size[1], size[2]))),
            MeshMaterial3d(material(rgb, 0.6)),
            Transform::from_translation(Vec3::from(pos)).with_rotation(Quat::from_rotation_y(0.4)),
        ));
    }
    for &(pos, radius, rgb) in SPHERES {
        commands.spawn((
            Mesh3d(meshes.add(Sphere::new(radius).mesh().uv(48, 24))),
            MeshMaterial3d(material(rgb, 0.3)),
            Transform::from_translation(Vec3::from(pos)),
        ));
    }
    // The sun: cascaded shadow maps (Bevy's default for a directional light with shadows).
    commands.spawn((
        DirectionalLight { illuminance: 8_000.0, shadow_maps_enabled: true, ..default() },
        Transform::from_xyz(0.0, 0.0, 0.0).looking_to(Vec3::new(-0.4, -1.0, -0.5), Vec3::Y),
    ));
    // A lamp near the viewer: a cube-map shadow pass per frame.
    commands.spawn((
        PointLight { intensity: 400_000.0, range: 30.0, shadow_maps_enabled: true, ..default() },
        Transform::from_xyz(1.5, 3.5, -1.0),
    ));
    // Heavy scenes (GPU timing): shadowless lights on a grid over the ground in front of the
    // viewer, every one shading the pixels within its range.
    let n = options.lights;
    let side = (n as f32).sqrt().ceil().max(1.0) as u32;
    for i in 0..n {
        let (gx, gz) = ((i % side) as f32, (i / side) as f32);
        let x = -12.0 + 24.0 * (gx + 0.5) / side as f32;
        let z = -1.5 - 24.0 * (gz + 0.5) / side as f32;
        let hue = 360.0 * i as f32 / n.max(1) as f32;
        commands.spawn((
            PointLight { color: Color::hsl(hue, 0.8, 0.6), intensity: 60_000.0, range: 8.0, shadow_maps_enabled: false, ..default() },
            Transform::from_xyz(x, 1.2, z),
        ));
    }
}

/// Gives each XR view camera the frame structure asked for, as it is spawned (bevy_mod_xr spawns
/// them when the session is created, before the first frame renders).
pub fn configure_xr_camera(add: On<Add, XrCamera>, options: Res<Options>, mut commands: Commands) {
    let mut camera = commands.entity(add.entity);
    camera.insert(match options.msaa {
        1 => Msaa::Off,
        2 => Msaa::Sample2,
        8 => Msaa::Sample8,
        _ => Msaa::Sample4,
    });
    camera.insert(match options.tonemapping {
        Tonemap::None => Tonemapping::None,
        Tonemap::Reinhard => Tonemapping::Reinhard,
        Tonemap::Aces => Tonemapping::AcesFitted,
        Tonemap::AgX => Tonemapping::AgX,
        Tonemap::TonyMcMapface => Tonemapping::TonyMcMapface,
    });
    if options.hdr {
        camera.insert(Hdr);
    }
    if options.bloom {
        camera.insert(Bloom::NATURAL);
    }
}
