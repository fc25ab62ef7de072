//! The binary reader against a model written by pycolmap (datasets/pycolmap_model.py wrote
//! datasets/fixtures/import/pycolmap: the `.bin` files, with current COLMAP's `rigs.bin` and
//! `frames.bin`, and `expected.json`, the model as pycolmap reads it back). Every number must
//! be read exactly, and each image's contract camera must project each 3D point onto the 2D
//! point pycolmap projected (`Camera.img_from_cam`, COLMAP's pixels: minus 0.5 in the
//! contract's).

use glam::{DVec2, DVec3};
use serde_json::Value;

use crate::model::contract_camera;
use crate::read_model;

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap()
}

#[test]
fn a_pycolmap_binary_model_reads_back_exactly() {
    let dir = igi_testkit::fixture("import/pycolmap");
    let want: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("expected.json")).unwrap()).unwrap();
    let (model, read) = read_model(&dir.join("sparse")).unwrap();
    assert_eq!(read.len(), 3, "{read:?}");
    assert!(read.iter().all(|p| p.extension().unwrap() == "bin"));

    let cams = want["cameras"].as_array().unwrap();
    assert_eq!(model.cameras.len(), cams.len());
    for (c, w) in model.cameras.iter().zip(cams) {
        assert_eq!(u64::from(c.id), w["id"].as_u64().unwrap());
        assert_eq!(c.model.name(), w["model"].as_str().unwrap());
        assert_eq!(
            (c.width, c.height),
            (w["width"].as_u64().unwrap(), w["height"].as_u64().unwrap())
        );
        let p: Vec<f64> = w["params"].as_array().unwrap().iter().map(f).collect();
        assert_eq!(c.params, p, "camera {}", c.id);
    }

    let imgs = want["images"].as_array().unwrap();
    assert_eq!(model.images.len(), imgs.len());
    let mut worst = 0.0f64;
    for (i, w) in model.images.iter().zip(imgs) {
        assert_eq!(u64::from(i.id), w["id"].as_u64().unwrap());
        assert_eq!(i.name, w["name"].as_str().unwrap());
        assert_eq!(u64::from(i.camera_id), w["camera_id"].as_u64().unwrap());
        let q: Vec<f64> = w["q"].as_array().unwrap().iter().map(f).collect();
        let t: Vec<f64> = w["t"].as_array().unwrap().iter().map(f).collect();
        assert_eq!((i.q.to_vec(), i.t.to_vec()), (q, t), "image {}", i.name);
        let pts = w["points2d"].as_array().unwrap();
        assert_eq!(i.points2d.len(), pts.len());
        for ((xy, id), p) in i.points2d.iter().zip(pts) {
            assert_eq!(
                (xy[0], xy[1], *id),
                (f(&p[0]), f(&p[1]), p[2].as_i64().unwrap())
            );
        }
        // the contract camera projects each 3D point where pycolmap did, minus 0.5 px
        let cam = contract_camera(&model, i).unwrap();
        for (xy, id) in i.points2d.iter().filter(|(_, id)| *id >= 0) {
            let x = model.points.iter().find(|p| p.id as i64 == *id).unwrap();
            let got = cam.project(DVec3::from_array(x.xyz)).unwrap();
            let want = DVec2::new(xy[0] - 0.5, xy[1] - 0.5);
            worst = worst.max(got.distance(want));
        }
    }
    eprintln!("contract cameras against pycolmap's projections: worst {worst:.2e} px");
    assert!(worst < 1e-9, "{worst} px");

    let pts = want["points"].as_array().unwrap();
    assert_eq!(model.points.len(), pts.len());
    for (p, w) in model.points.iter().zip(pts) {
        assert_eq!(p.id, w["id"].as_u64().unwrap());
        let xyz: Vec<f64> = w["xyz"].as_array().unwrap().iter().map(f).collect();
        assert_eq!(p.xyz.to_vec(), xyz);
        let rgb: Vec<u8> = w["rgb"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap() as u8)
            .collect();
        assert_eq!(p.rgb.to_vec(), rgb);
        assert_eq!(p.error, f(&w["error"]));
        let track: Vec<(u32, u32)> = w["track"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| (e[0].as_u64().unwrap() as u32, e[1].as_u64().unwrap() as u32))
            .collect();
        assert_eq!(p.track, track);
    }
}
