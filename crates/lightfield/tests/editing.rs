//! Editing: a glossy sphere's surface light field rendered rotated by 30 degrees and deformed to
//! an ellipsoid (same triangles and UVs, new normals), against path-traced renders of the
//! rotated / deformed object.

mod common;

use common::{camera_toward, psnr, sphere_dirs};
use glam::{Mat3, Vec3};
use igi_brdf::Lobe;
use igi_geometry::atlas::{build_atlas, AtlasOptions};
use igi_geometry::procedural::uv_sphere;
use igi_geometry::TriMesh;
use igi_imaging::HdrImage;
use igi_lightfield::{BuildOptions, Method, Prepared, RenderSlfOptions, View};
use igi_render::embree::RtScene;
use igi_render::{
    render_image, Albedo, Environment, Lighting, Material, RenderOptions, Scene, Texture,
};

fn transformed(mesh: &TriMesh, f: impl Fn(Vec3) -> Vec3) -> TriMesh {
    let mut m = mesh.clone();
    for p in &mut m.positions {
        *p = f(Vec3::from_array(*p)).to_array();
    }
    m.normals = None;
    m.compute_vertex_normals();
    m
}

#[test]
#[ignore = "not met yet: the rotated sphere renders at 20.5 dB against its truth (goal 30 dB); the stored median colour carries the capture's lighting and moves with the surface (docs/LIGHTFIELD.md)"]
fn a_rotated_and_a_deformed_sphere_render_close_to_their_truth() {
    let mesh = uv_sphere(24, 48, 0.5);
    let atlas = build_atlas(
        &mesh,
        AtlasOptions {
            resolution: 96,
            gutter: 2,
        },
    )
    .unwrap();
    let mut tex = HdrImage::new(atlas.resolution, atlas.resolution);
    for (i, p) in atlas.position.pixels.iter().enumerate() {
        tex.pixels[i] = common::albedo(Vec3::from_array(*p)).to_array();
    }
    let material = Material {
        albedo: Albedo::Texture(Texture::from_image(&tex)),
        lobes: vec![Lobe {
            rho: Vec3::splat(4.0),
            cxy: -1.0,
            cz: 1.0,
            n: 60.0,
        }],
        lobe_map: None,
    };
    let probe = igi_imaging::read_image(&igi_testkit::shared_data(
        "light_probes/probulator_latlong_256x128/pisa.hdr",
    ))
    .unwrap();
    let lighting = Lighting {
        environment: Some(Environment::from_image(&probe, 1.0).unwrap()),
        sun: None,
    };
    let shoot = |m: &TriMesh, dir: Vec3, spp: u32, seed: u64| {
        let scene = Scene::new(vec![("sphere".into(), m.clone(), material.clone())]).unwrap();
        let cam = camera_toward(dir, 3.0, 48);
        let img = render_image(
            &scene,
            &lighting,
            &cam,
            &RenderOptions {
                spp,
                seed,
                indirect: 1,
                russian_roulette: false,
            },
            &|_| {},
        )
        .unwrap()
        .mean;
        (cam, img)
    };
    let dirs = sphere_dirs(120, 0.0);
    let views: Vec<_> = dirs
        .iter()
        .enumerate()
        .map(|(i, d)| shoot(&atlas.mesh, *d, 16, i as u64))
        .collect();
    let rt = RtScene::new(&[(
        atlas.mesh.positions.as_slice(),
        atlas.mesh.indices.as_slice(),
    )])
    .unwrap();
    let vs: Vec<View> = views
        .iter()
        .map(|(c, i)| View {
            camera: c,
            image: i,
        })
        .collect();
    let prep = Prepared::new(&atlas, &rt, &vs, 3);
    let field = prep
        .fit(Method::Pfa { q: 2 }, &BuildOptions::default())
        .unwrap();
    let eye = Vec3::new(0.7, -0.5, 0.5).normalize();
    let rot = Mat3::from_axis_angle(Vec3::new(1.0, 1.0, 0.0).normalize(), 30f32.to_radians());
    let mut results = Vec::new();
    for (name, m) in [
        ("rotated 30 deg", transformed(&atlas.mesh, |p| rot * p)),
        (
            "ellipsoid",
            transformed(&atlas.mesh, |p| p * Vec3::new(1.3, 1.0, 0.75)),
        ),
    ] {
        let (cam, truth) = shoot(&m, eye, 64, 777);
        let (img, alpha) = field
            .render(&m, &cam, &RenderSlfOptions::default())
            .unwrap();
        let p = psnr(&img, &alpha, &truth);
        eprintln!("{name}: PSNR {p:.2} dB against the path-traced truth");
        results.push(p);
    }
    assert!(results[0] >= 30.0, "rotated: {:.2} dB", results[0]);
    assert!(results[1] >= 28.0, "ellipsoid: {:.2} dB", results[1]);
}
