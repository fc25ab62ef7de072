//! Editing: a glossy sphere's surface light field rendered rotated by 30 degrees and deformed to
//! an ellipsoid (same triangles and UVs, new normals), against path-traced renders of the
//! rotated / deformed object under the same (fixed) lighting.

use crate::common;

use common::{camera_toward, psnr, sphere_dirs};
use glam::{Mat3, Vec3};
use igi_brdf::Lobe;
use igi_camera::Camera;
use igi_geometry::atlas::{build_atlas, Atlas, AtlasOptions};
use igi_geometry::procedural::uv_sphere;
use igi_geometry::TriMesh;
use igi_imaging::HdrImage;
use igi_lightfield::{BuildOptions, Method, Prepared, RenderSlfOptions, SurfaceLightField, View};
use igi_raycast::RtScene;
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

/// The sphere's atlas, material and lighting.
struct Setup {
    atlas: Atlas,
    material: Material,
    lighting: Lighting,
}

/// The textured sphere under `pisa.hdr`; `diffuse` scales the procedural albedo, `glossy` the
/// Lafortune lobe (rho 4, n = 60).
fn setup(diffuse: f32, glossy: f32) -> Setup {
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
        tex.pixels[i] = (common::albedo(Vec3::from_array(*p)) * diffuse).to_array();
    }
    let material = Material {
        albedo: Albedo::Texture(Texture::from_image(&tex)),
        lobes: vec![Lobe {
            rho: Vec3::splat(4.0 * glossy),
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
    Setup {
        atlas,
        material,
        lighting,
    }
}

impl Setup {
    /// A path-traced photograph of `m` (the atlas mesh or an edited copy) from direction `dir`.
    fn shoot(&self, m: &TriMesh, dir: Vec3, spp: u32, seed: u64) -> (Camera, HdrImage) {
        let scene = Scene::new(vec![("sphere".into(), m.clone(), self.material.clone())]).unwrap();
        let cam = camera_toward(dir, 3.0, 48);
        let opts = RenderOptions {
            spp,
            seed,
            indirect: 1,
            russian_roulette: false,
            stratified: false,
            adaptive: false,
        };
        let img = render_image(&scene, &self.lighting, &cam, &opts, &|_| {})
            .unwrap()
            .mean;
        (cam, img)
    }

    /// The PFA q = 2 field of 120 views of 48 x 48 at 16 spp.
    fn field(&self) -> SurfaceLightField {
        let mesh = &self.atlas.mesh;
        let views: Vec<_> = sphere_dirs(120, 0.0)
            .iter()
            .enumerate()
            .map(|(i, d)| self.shoot(mesh, *d, 16, i as u64))
            .collect();
        let rt = RtScene::new(&[(mesh.positions.as_slice(), mesh.indices.as_slice())]).unwrap();
        let vs: Vec<View> = views
            .iter()
            .map(|(c, i)| View {
                camera: c,
                image: i,
            })
            .collect();
        Prepared::new(&self.atlas, &rt, &vs, 3)
            .fit(Method::Pfa { q: 2 }, &BuildOptions::default())
            .unwrap()
    }

    /// PSNR of the field's render of `m` against the path-traced `m` (256 spp, so that its noise
    /// stays below the errors measured), from a direction that is
    /// no capture view's.
    fn edit_psnr(&self, field: &SurfaceLightField, m: &TriMesh) -> f64 {
        let eye = Vec3::new(0.7, -0.5, 0.5).normalize();
        let (cam, truth) = self.shoot(m, eye, 256, 777);
        let (img, alpha) = field.render(m, &cam, &RenderSlfOptions::default()).unwrap();
        psnr(&img, &alpha, &truth)
    }
}

/// The unedited sphere, the sphere rotated by 30 degrees, and the ellipsoid.
fn edits(mesh: &TriMesh) -> [(&'static str, TriMesh); 3] {
    let rot = Mat3::from_axis_angle(Vec3::new(1.0, 1.0, 0.0).normalize(), 30f32.to_radians());
    [
        ("unedited", transformed(mesh, |p| p)),
        ("rotated 30 deg", transformed(mesh, |p| rot * p)),
        (
            "ellipsoid",
            transformed(mesh, |p| p * Vec3::new(1.3, 1.0, 0.75)),
        ),
    ]
}

/// The rotated mesh with the unedited mesh's normals (the edit not applied to the normals).
fn with_stale_normals(mesh: &TriMesh) -> TriMesh {
    let [(_, unedited), (_, mut rotated), _] = edits(mesh);
    rotated.normals = unedited.normals;
    rotated
}

#[test]
#[ignore = "diagnostic (about 25 s): the edits of a diffuse-only, a glossy-only and the full sphere (docs/LIGHTFIELD.md)"]
fn editing_error_by_material() {
    for (name, d, g) in [
        ("diffuse", 1.0, 0.0),
        ("glossy", 0.0, 1.0),
        ("both", 1.0, 1.0),
    ] {
        let s = setup(d, g);
        let field = s.field();
        for (edit, m) in edits(&s.atlas.mesh) {
            eprintln!("{name}: {edit}: PSNR {:.2} dB", s.edit_psnr(&field, &m));
        }
        let stale = with_stale_normals(&s.atlas.mesh);
        eprintln!(
            "{name}: rotated, stale normals: PSNR {:.2} dB",
            s.edit_psnr(&field, &stale)
        );
    }
}

#[test]
fn the_edit_reflects_about_the_new_normals() {
    let s = setup(1.0, 1.0);
    let field = s.field();
    let [_, (_, rotated), _] = edits(&s.atlas.mesh);
    let edited = s.edit_psnr(&field, &rotated);
    let stale = s.edit_psnr(&field, &with_stale_normals(&s.atlas.mesh));
    eprintln!(
        "rotated 30 deg: {edited:.2} dB with its own normals, {stale:.2} dB with the old ones"
    );
    // measured 2026-11-24: 19.66 dB against 17.76 dB
    assert!(
        edited >= stale + 1.0,
        "new normals {edited:.2} dB vs stale normals {stale:.2} dB"
    );
}

#[test]
#[ignore = "not met: rotated 20.1 dB (goal 30), ellipsoid 20.3 dB (goal 28); the unedited sphere itself reaches 22.9 dB (docs/LIGHTFIELD.md, Editing)"]
fn a_rotated_and_a_deformed_sphere_render_close_to_their_truth() {
    let s = setup(1.0, 1.0);
    let field = s.field();
    let r: Vec<f64> = edits(&s.atlas.mesh)
        .iter()
        .map(|(name, m)| {
            let p = s.edit_psnr(&field, m);
            eprintln!("{name}: PSNR {p:.2} dB against the path-traced truth");
            p
        })
        .collect();
    assert!(r[1] >= 30.0, "rotated: {:.2} dB", r[1]);
    assert!(r[2] >= 28.0, "ellipsoid: {:.2} dB", r[2]);
}
