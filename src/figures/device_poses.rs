//! The device's poses: the hexapod in frame B seen from above and from the side, its base ring,
//! its platform and legs at the datum and at the station farthest from it, and the tool point
//! at every evaluated dwell (`docs/spec/device-format.md`, "Conventions"). It shows what was
//! measured: the set-up, how far the test moved it, and that the poses found follow the
//! commanded line.

use dbbcal_machine::hexapod::Hexapod;
use dbbcal_machine::pose::Pose;

use crate::pipeline::DeviceStage;
use crate::report::{GeometryFigure, GeometryView, NamedSeries};

/// Polylines in 3-D, NaN-separated, projected on two axes.
#[derive(Default)]
struct Lines3 {
    points: Vec<[f64; 3]>,
}

impl Lines3 {
    fn polyline(&mut self, pts: impl IntoIterator<Item = [f64; 3]>) {
        if !self.points.is_empty() {
            self.points.push([f64::NAN; 3]);
        }
        self.points.extend(pts);
    }

    fn view(&self, name: &str, a: usize, b: usize) -> NamedSeries {
        NamedSeries {
            name: name.into(),
            x: self.points.iter().map(|p| p[a]).collect(),
            y: self.points.iter().map(|p| p[b]).collect(),
        }
    }
}

/// t + R q in B for a point q of P, mm.
fn in_base(pose: &Pose, q: [f64; 3]) -> [f64; 3] {
    let (t, r) = (pose.translation_mm(), pose.rotation());
    std::array::from_fn(|i| t[i] + (0..3).map(|j| r[(i, j)] * q[j]).sum::<f64>())
}

fn platform_at(device: &Hexapod, pose: &Pose) -> [[f64; 3]; 6] {
    device.platform_mm.map(|p| in_base(pose, p))
}

/// The ring closed, and the six legs, of the device at `pose`.
fn legs_and_ring(device: &Hexapod, pose: &Pose) -> (Lines3, Lines3) {
    let top = platform_at(device, pose);
    let mut ring = Lines3::default();
    ring.polyline(top.iter().chain(top.first()).copied());
    let mut legs = Lines3::default();
    for (b, p) in device.base_mm.iter().zip(&top) {
        legs.polyline([*b, *p]);
    }
    (ring, legs)
}

/// The figure, when the device test found poses.
pub(super) fn device_poses_figure(s: &DeviceStage, device: &Hexapod) -> Option<GeometryFigure> {
    let t = s.outcome.as_ref().ok()?;
    let datum = t.dwells.get(t.datum)?;
    let datum_pose = datum.pose?;
    let d0 = datum.input.position_mm;
    let far = t
        .dwells
        .iter()
        .filter(|d| d.errors.is_some())
        .filter_map(|d| {
            let moved = (0..3)
                .map(|k| (d.input.position_mm[k] - d0[k]).powi(2))
                .sum::<f64>();
            Some((moved, d.pose?, d.input.station))
        })
        .max_by(|a, b| a.0.total_cmp(&b.0))?;
    let mut base = Lines3::default();
    base.polyline(device.base_mm.iter().chain(device.base_mm.first()).copied());
    let (ring0, legs0) = legs_and_ring(device, &datum_pose);
    let (ring1, legs1) = legs_and_ring(device, &far.1);
    let path: Vec<[f64; 3]> = t
        .dwells
        .iter()
        .filter_map(|d| Some(in_base(&d.pose?, device.tool_point_mm)))
        .collect();
    let datum_station = s.dwells.get(t.datum).map_or(0, |d| d.station);
    let view = |title: &str, a: usize, b: usize| {
        let names = ["x", "y", "z"];
        GeometryView {
            title: title.into(),
            x_label: format!("{} in B (mm)", names[a]),
            y_label: format!("{} in B (mm)", names[b]),
            lines: vec![
                base.view("base joints", a, b),
                legs0.view(
                    &format!("legs at the datum (station {datum_station})"),
                    a,
                    b,
                ),
                ring0.view("platform at the datum", a, b),
                legs1.view(&format!("legs at station {}", far.2), a, b),
                ring1.view(&format!("platform at station {}", far.2), a, b),
            ],
            points: vec![NamedSeries {
                name: "tool point at each dwell".into(),
                x: path.iter().map(|p| p[a]).collect(),
                y: path.iter().map(|p| p[b]).collect(),
            }],
        }
    };
    Some(GeometryFigure {
        title: format!("Device {}: the poses measured", s.device.id),
        subtitle: format!(
            "frame B (the base); {} dwells with a pose; the station farthest from the datum is {:.1} mm away",
            path.len(),
            far.0.sqrt()
        ),
        views: vec![view("from above (x, y)", 0, 1), view("from the side (x, z)", 0, 2)],
    })
}
