//! Agisoft Metashape's camera XML (File > Export > Export Cameras, "Agisoft XML") as contract
//! cameras.
//!
//! The file: `<document><chunk>` with `<sensors>` (each `<sensor id type="frame">` with
//! `<resolution width height/>` and `<calibration class="adjusted">` holding `f`, `cx`, `cy`,
//! `b1`, `b2`, `k1`..`k4`, `p1`..`p4`), `<cameras>` (each `<camera id label sensor_id
//! [component_id]>` with a `<transform>` of 16 numbers, row-major camera to chunk; cameras may
//! sit in `<group>`s; a camera without a transform was not aligned and is left out),
//! `<components>` (each `<component id>` with a `<transform>` of `<rotation>` (9 numbers,
//! row-major), `<translation>`, `<scale>` and a `<partition><camera_ids>`), and a chunk-level
//! `<transform>` of the same parts (or 16 numbers).
//!
//! Frames: a camera's transform maps its own axes (OpenCV's: x right, y down, z forward) into
//! its component's frame; the component's transform `x -> scale R x + translation` maps that
//! into the chunk's frame, and the chunk's transform maps the chunk's frame into the world (the
//! chunk's coordinate system). A camera belongs to the component its `component_id` names, else
//! the one whose `camera_ids` lists it, else (when there is exactly one component) that one.
//! Absent transforms are the identity.
//!
//! The camera model (Agisoft Metashape User Manual, Professional Edition 1.5 to 2.x, Appendix C
//! "Camera models", frame cameras): with `(x, y) = (X/Z, Y/Z)` and `r^2 = x^2 + y^2`,
//! `x' = x (1 + K1 r^2 + K2 r^4 + K3 r^6 + K4 r^8) + P1 (r^2 + 2x^2) + 2 P2 x y`,
//! `y' = y (1 + ...) + P2 (r^2 + 2y^2) + 2 P1 x y`, and
//! `u = w/2 + cx + x' (f + B1) + y' B2`, `v = h/2 + cy + y' f`, in the manual's image
//! coordinates, whose origin is the top-left corner of the image, so that the centre of the
//! top-left pixel is at (0.5, 0.5). (This session could not retrieve the manual's own text;
//! the equations above are those an Agisoft forum post of 5 August 2022 quotes from "Appendix
//! C of the Metashape Pro documentation, on Frame cameras", the P1/P2 order is the one the
//! community "Metashape expert manual" page "Metashape's distortion model and converting to
//! OpenCV / Colmap" documents, and nerfstudio's own Metashape converter
//! (`nerfstudio/process_data/metashape_utils.py`) takes `w/2 + cx` as its principal point, in
//! nerfstudio's pixels whose centres are at +0.5: the same convention.)
//!
//! So the contract camera (OpenCV's model, the centre of the top-left pixel at (0, 0)) is
//! exactly `fx = f + B1`, `fy = f`, `cx = w/2 + cx - 0.5`, `cy = h/2 + cy - 0.5`,
//! `k1, k2, k3 = K1, K2, K3`, and OpenCV's `p1 = P2`, `p2 = P1` (Metashape's tangential terms
//! are OpenCV's swapped). `B2` (skew), `K4`, `P3` and `P4` have no contract counterpart: a
//! nonzero one is refused by name, as is any sensor type but `frame` (fisheye, spherical,
//! cylindrical, RPC).

use std::collections::HashMap;
use std::path::Path;

use glam::{DMat3, DVec3};
use igi_camera::{Camera, Distortion, Intrinsics};
use roxmltree::{Document, Node};

use crate::error::ImportError;
use crate::model::from_pixel_corner_origin;
use crate::source::{pose_from_camera_to_world, Affine, CameraSet, PosedImage};

/// An element's line in the file, for errors.
fn line_of(doc: &Document, node: Node) -> usize {
    doc.text_pos_at(node.range().start).row as usize
}

struct Ctx<'a> {
    path: &'a Path,
    doc: &'a Document<'a>,
}

impl Ctx<'_> {
    fn err(&self, node: Node, problem: impl Into<String>) -> ImportError {
        ImportError::text(self.path, line_of(self.doc, node), problem)
    }

    fn numbers(&self, node: Node, n: usize) -> Result<Vec<f64>, ImportError> {
        let text = node.text().unwrap_or("");
        let v = text
            .split_whitespace()
            .map(|w| w.parse::<f64>().ok().filter(|x| x.is_finite()))
            .collect::<Option<Vec<f64>>>()
            .ok_or_else(|| {
                self.err(
                    node,
                    format!("<{}> `{text}` is not numbers", node.tag_name().name()),
                )
            })?;
        if v.len() != n {
            return Err(self.err(
                node,
                format!(
                    "<{}> holds {} numbers, not {n}",
                    node.tag_name().name(),
                    v.len()
                ),
            ));
        }
        Ok(v)
    }

    fn number(&self, node: Node) -> Result<f64, ImportError> {
        Ok(self.numbers(node, 1)?[0])
    }

    fn attr<'n>(&self, node: Node<'n, 'n>, name: &str) -> Result<&'n str, ImportError> {
        node.attribute(name).ok_or_else(|| {
            self.err(
                node,
                format!("<{}> has no `{name}` attribute", node.tag_name().name()),
            )
        })
    }

    /// A `<transform>`: 16 numbers (row-major 4x4) or `<rotation>`, `<translation>`,
    /// `<scale>` parts (each optional).
    fn transform(&self, node: Node) -> Result<Affine, ImportError> {
        let parts: Vec<Node> = node.children().filter(Node::is_element).collect();
        if parts.is_empty() {
            return self.matrix(node);
        }
        let mut a = Affine::IDENTITY;
        let mut scale = 1.0;
        for p in parts {
            match p.tag_name().name() {
                "rotation" => {
                    let r = self.numbers(p, 9)?;
                    a.m = DMat3::from_cols_slice(&r).transpose();
                    if !crate::source::is_rotation(a.m) {
                        return Err(self.err(p, "<rotation> is not a rotation matrix"));
                    }
                }
                "translation" => a.t = DVec3::from_slice(&self.numbers(p, 3)?),
                "scale" => {
                    scale = self.number(p)?;
                    if !(scale > 0.0) {
                        return Err(self.err(p, format!("<scale> {scale} is not positive")));
                    }
                }
                _ => {}
            }
        }
        a.m *= scale;
        Ok(a)
    }

    /// 16 numbers, a row-major 4x4 affine matrix (last row 0 0 0 1).
    fn matrix(&self, node: Node) -> Result<Affine, ImportError> {
        let v = self.numbers(node, 16)?;
        let last = [v[12], v[13], v[14], v[15]];
        if (last[0].abs() + last[1].abs() + last[2].abs() + (last[3] - 1.0).abs()) > 1e-9 {
            return Err(self.err(
                node,
                format!("<transform> last row {last:?} is not 0 0 0 1"),
            ));
        }
        let m = DMat3::from_cols_array_2d(&[
            [v[0], v[4], v[8]],
            [v[1], v[5], v[9]],
            [v[2], v[6], v[10]],
        ]);
        Ok(Affine {
            m,
            t: DVec3::new(v[3], v[7], v[11]),
        })
    }
}

/// One sensor's contract intrinsics and size.
struct Sensor {
    width: u32,
    height: u32,
    intrinsics: Intrinsics,
}

fn child<'a>(node: Node<'a, 'a>, name: &str) -> Option<Node<'a, 'a>> {
    node.children().find(|c| c.has_tag_name(name))
}

fn sensor(cx: &Ctx, node: Node) -> Result<Sensor, ImportError> {
    let id = node.attribute("id").unwrap_or("?");
    let kind = node.attribute("type").unwrap_or("frame");
    if kind != "frame" {
        return Err(cx.err(
            node,
            format!(
                "sensor {id}: camera type `{kind}` is not supported: the contract camera is \
                 OpenCV's pinhole (Metashape type `frame`)"
            ),
        ));
    }
    let calibs: Vec<Node> = node
        .children()
        .filter(|c| c.has_tag_name("calibration"))
        .collect();
    let calib = calibs
        .iter()
        .find(|c| c.attribute("class") == Some("adjusted"))
        .or_else(|| calibs.first())
        .copied()
        .ok_or_else(|| cx.err(node, format!("sensor {id} has no <calibration>")))?;
    if let Some(k) = calib.attribute("type").filter(|k| *k != "frame") {
        return Err(cx.err(
            calib,
            format!("sensor {id}: calibration type `{k}` is not supported (only `frame`)"),
        ));
    }
    let res = child(calib, "resolution")
        .or_else(|| child(node, "resolution"))
        .ok_or_else(|| cx.err(calib, format!("sensor {id} has no <resolution>")))?;
    let size = |name: &str| -> Result<u32, ImportError> {
        let v = cx.attr(res, name)?;
        v.trim()
            .parse::<u32>()
            .ok()
            .filter(|v| *v > 0)
            .ok_or_else(|| cx.err(res, format!("<resolution> {name} `{v}` is not a size")))
    };
    let (width, height) = (size("width")?, size("height")?);
    let mut p: HashMap<&str, f64> = HashMap::new();
    let mut at: HashMap<&str, Node> = HashMap::new();
    for c in calib.children().filter(Node::is_element) {
        let name = c.tag_name().name();
        if [
            "f", "cx", "cy", "b1", "b2", "k1", "k2", "k3", "k4", "p1", "p2", "p3", "p4",
        ]
        .contains(&name)
        {
            p.insert(name, cx.number(c)?);
            at.insert(name, c);
        }
    }
    let f = *p
        .get("f")
        .ok_or_else(|| cx.err(calib, format!("sensor {id}: <calibration> has no <f>")))?;
    let g = |k: &str| p.get(k).copied().unwrap_or(0.0);
    for (k, why) in [
        ("b2", "skew (the contract camera has none)"),
        (
            "k4",
            "an 8th-order radial term (the contract has k1, k2, k3)",
        ),
        ("p3", "a higher-order tangential term"),
        ("p4", "a higher-order tangential term"),
    ] {
        if g(k) != 0.0 {
            return Err(cx.err(
                at[k],
                format!(
                    "sensor {id}: {k} = {} is {why}: not representable by the contract camera; \
                     recalibrate with {k} fixed to 0",
                    g(k)
                ),
            ));
        }
    }
    let fx = f + g("b1");
    if !(f > 0.0 && fx > 0.0) {
        return Err(cx.err(
            calib,
            format!(
                "sensor {id}: f = {f}, b1 = {} is not a focal length",
                g("b1")
            ),
        ));
    }
    // Metashape's P1 multiplies (r^2 + 2x^2) in x': OpenCV's p2; its P2 is OpenCV's p1
    let dist = Distortion::from_array([g("k1"), g("k2"), g("p2"), g("p1"), g("k3")]);
    // cx, cy are offsets from the image centre
    let intrinsics = from_pixel_corner_origin(
        fx,
        f,
        f64::from(width) / 2.0 + g("cx"),
        f64::from(height) / 2.0 + g("cy"),
        dist,
    );
    Ok(Sensor {
        width,
        height,
        intrinsics,
    })
}

/// The components' transforms by id, and which component each camera id is listed in.
type Components = (HashMap<String, Affine>, HashMap<String, String>);

fn components(cx: &Ctx, chunk: Node) -> Result<Components, ImportError> {
    let mut tf = HashMap::new();
    let mut member = HashMap::new();
    let Some(comps) = child(chunk, "components") else {
        return Ok((tf, member));
    };
    for c in comps.children().filter(|c| c.has_tag_name("component")) {
        let id = cx.attr(c, "id")?.to_string();
        let a = match child(c, "transform") {
            Some(t) => cx.transform(t)?,
            None => Affine::IDENTITY,
        };
        if let Some(ids) = child(c, "partition").and_then(|p| child(p, "camera_ids")) {
            for cam in ids.text().unwrap_or("").split_whitespace() {
                member.insert(cam.to_string(), id.clone());
            }
        }
        tf.insert(id, a);
    }
    Ok((tf, member))
}

/// The cameras of a Metashape camera XML file (in its chunk's world frame).
pub fn read_metashape(path: &Path) -> Result<CameraSet, ImportError> {
    let text = std::fs::read_to_string(path).map_err(|source| ImportError::Read {
        path: path.to_path_buf(),
        what: "the Metashape cameras XML",
        source,
    })?;
    let doc = Document::parse(&text)
        .map_err(|e| ImportError::text(path, e.pos().row as usize, format!("not XML: {e}")))?;
    let cx = Ctx { path, doc: &doc };
    let root = doc.root_element();
    let chunk = if root.has_tag_name("chunk") {
        root
    } else {
        child(root, "chunk").ok_or_else(|| {
            cx.err(
                root,
                format!(
                    "<{}> holds no <chunk>: not a Metashape cameras XML",
                    root.tag_name().name()
                ),
            )
        })?
    };
    let sensors_node =
        child(chunk, "sensors").ok_or_else(|| cx.err(chunk, "<chunk> has no <sensors>"))?;
    let cameras_node =
        child(chunk, "cameras").ok_or_else(|| cx.err(chunk, "<chunk> has no <cameras>"))?;
    let mut sensors = HashMap::new();
    for s in sensors_node.children().filter(|c| c.has_tag_name("sensor")) {
        sensors.insert(cx.attr(s, "id")?.to_string(), (s, None::<Sensor>));
    }
    let world = match child(chunk, "transform") {
        Some(t) => cx.transform(t)?,
        None => Affine::IDENTITY,
    };
    let (comp_tf, member) = components(&cx, chunk)?;
    let mut set = CameraSet {
        read: vec![path.to_path_buf()],
        images_file: path.to_path_buf(),
        ..CameraSet::default()
    };
    for cam in cameras_node
        .descendants()
        .filter(|c| c.has_tag_name("camera"))
    {
        let label = cx.attr(cam, "label")?.to_string();
        let Some(tnode) = child(cam, "transform") else {
            set.unposed.push(label);
            continue;
        };
        let sid = cx.attr(cam, "sensor_id")?;
        let (snode, parsed) = sensors.get_mut(sid).ok_or_else(|| {
            cx.err(
                cam,
                format!("camera `{label}` names sensor {sid}, which <sensors> lacks"),
            )
        })?;
        if parsed.is_none() {
            *parsed = Some(sensor(&cx, *snode)?);
        }
        let s = parsed.as_ref().expect("parsed above");
        let id = cam.attribute("id").unwrap_or("");
        let comp = cam
            .attribute("component_id")
            .map(str::to_string)
            .or_else(|| member.get(id).cloned())
            .or_else(|| {
                (comp_tf.len() == 1)
                    .then(|| comp_tf.keys().next().cloned())
                    .flatten()
            });
        let comp = match comp {
            Some(c) => *comp_tf.get(&c).ok_or_else(|| {
                cx.err(
                    cam,
                    format!("camera `{label}` names component {c}, which <components> lacks"),
                )
            })?,
            None => Affine::IDENTITY,
        };
        let to_world = world.then_inner(comp).then_inner(cx.matrix(tnode)?);
        let pose = pose_from_camera_to_world(to_world.m, to_world.t).ok_or_else(|| {
            cx.err(
                tnode,
                format!(
                    "camera `{label}`: its transform (with the component's and the chunk's) is \
                     not a rotation times a uniform scale"
                ),
            )
        })?;
        set.images.push(PosedImage {
            name: label,
            camera: Camera {
                width: s.width,
                height: s.height,
                intrinsics: s.intrinsics,
                pose,
            },
        });
    }
    set.cameras = sensors.values().filter(|(_, p)| p.is_some()).count();
    Ok(set)
}
