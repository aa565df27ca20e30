//! Objects on the water: spawning, motion (random walks, boat turns, drift) and timed
//! class changes, precomputed per object at [`OBJECT_DT_S`] and interpolated.

use crate::scenario::{EventKind, ObjectClass, ObjectGroup, Scenario};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// Sampling step of object tracks. Objects move at most ~15 m/s, so 10 Hz with linear
/// interpolation is smooth to a few centimetres.
pub const OBJECT_DT_S: f64 = 0.1;

/// First RNG stream used for objects; object `i` uses `STREAM_OBJECTS + i`, so adding an
/// object group never changes the paths of the objects before it.
const STREAM_OBJECTS: u64 = 1000;

/// One object over the whole scenario.
#[derive(Debug, Clone)]
pub struct SimObject {
    /// Track id (1-based, unique in the scenario; MOT `id`, SeaDronesSee `track_id`).
    pub id: u32,
    /// Class at the start.
    pub initial_class: ObjectClass,
    /// `(at_s, new_class)` changes, in time order.
    pub class_changes: Vec<(f64, ObjectClass)>,
    /// Swimmers: wears a life jacket until this time (`f64::INFINITY`: always;
    /// `f64::NEG_INFINITY`: never).
    pub lifejacket_until_s: f64,
    /// Time the object appears (0 for spawned objects, later for dropped life jackets).
    pub appears_s: f64,
    /// Length along its heading.
    pub length_m: f64,
    /// Width across its heading.
    pub width_m: f64,
    /// Height of the visible part above the water.
    pub height_m: f64,
    /// Colour variant chosen at spawn (life jacket, hull, ...), an index into the
    /// renderer's palettes.
    pub palette: u32,
    /// Samples `(north_m, east_m, heading_rad unwrapped)` at `appears_s + k * OBJECT_DT_S`.
    track: Vec<[f64; 3]>,
}

/// The state of one object at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObjectState {
    /// Track id.
    pub id: u32,
    /// Class now.
    pub class: ObjectClass,
    /// Reference point on the sea surface, local NED (down = 0).
    pub pos_ned_m: [f64; 3],
    /// Heading of the object's long axis, radians clockwise from north.
    pub heading_rad: f64,
    /// Speed over ground.
    pub speed_mps: f64,
    /// Swimmers: wearing a life jacket.
    pub lifejacket: bool,
    /// Length along heading.
    pub length_m: f64,
    /// Width across heading.
    pub width_m: f64,
    /// Height above water.
    pub height_m: f64,
    /// Colour variant.
    pub palette: u32,
}

impl SimObject {
    /// The state at `t_s`, or `None` before the object appears.
    pub fn at(&self, t_s: f64) -> Option<ObjectState> {
        if t_s < self.appears_s || self.track.is_empty() {
            return None;
        }
        let x = (t_s - self.appears_s) / OBJECT_DT_S;
        let last = self.track.len() - 1;
        let i = (x.floor() as usize).min(last);
        let j = (i + 1).min(last);
        let f = (x - i as f64).clamp(0.0, 1.0);
        let (a, b) = (self.track[i], self.track[j]);
        let n = a[0] + (b[0] - a[0]) * f;
        let e = a[1] + (b[1] - a[1]) * f;
        let h = a[2] + (b[2] - a[2]) * f;
        let speed = if i == j {
            0.0
        } else {
            (b[0] - a[0]).hypot(b[1] - a[1]) / OBJECT_DT_S
        };
        let class = self
            .class_changes
            .iter()
            .rev()
            .find(|(at, _)| t_s >= *at)
            .map_or(self.initial_class, |(_, c)| *c);
        Some(ObjectState {
            id: self.id,
            class,
            pos_ned_m: [n, e, 0.0],
            heading_rad: h,
            speed_mps: speed,
            lifejacket: t_s < self.lifejacket_until_s,
            length_m: self.length_m,
            width_m: self.width_m,
            height_m: self.height_m,
            palette: self.palette,
        })
    }
}

/// Default speed range of a class through the water.
fn default_speed_range(class: ObjectClass) -> [f64; 2] {
    match class {
        ObjectClass::Swimmer => [0.0, 1.0],
        ObjectClass::Boat => [2.0, 12.0],
        ObjectClass::Jetski => [5.0, 15.0],
        ObjectClass::LifeSavingAppliance => [0.0, 0.3],
        ObjectClass::Buoy => [0.0, 0.0],
    }
}

/// Size `(length, width, height)` of a class, drawn once per object.
fn draw_size(class: ObjectClass, rng: &mut ChaCha8Rng) -> (f64, f64, f64) {
    match class {
        // Head and shoulders in a life jacket, mostly submerged.
        ObjectClass::Swimmer => (
            rng.random_range(0.55..0.75),
            rng.random_range(0.45..0.6),
            0.3,
        ),
        ObjectClass::Boat => {
            let l = rng.random_range(5.0..12.0);
            (l, l * rng.random_range(0.32..0.42), 1.2 + 0.1 * l)
        }
        ObjectClass::Jetski => (3.2, 1.2, 1.0),
        ObjectClass::LifeSavingAppliance => (0.75, 0.75, 0.15),
        ObjectClass::Buoy => {
            let d = rng.random_range(0.6..1.0);
            (d, d, 1.0)
        }
    }
}

/// Generates every object of the scenario, including those created by events.
pub fn generate(scenario: &Scenario, seed: u64) -> Vec<SimObject> {
    let n_steps = ((scenario.duration_s + 2.0) / OBJECT_DT_S).ceil() as usize + 1;
    let current = scenario.sea.current_ne_mps;
    let mut objects = Vec::new();
    let mut group_first_index = Vec::new();
    let mut stream = STREAM_OBJECTS;
    for group in &scenario.objects {
        group_first_index.push(objects.len());
        for _ in 0..group.count {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            rng.set_stream(stream);
            stream += 1;
            let id = objects.len() as u32 + 1;
            objects.push(spawn(group, id, current, n_steps, &mut rng));
        }
    }
    for event in &scenario.events {
        let Some(&first) = group_first_index.get(event.group) else {
            continue;
        };
        let index = first + event.member as usize;
        if index >= objects.len() {
            continue;
        }
        match event.kind {
            EventKind::ChangeClass => {
                if let Some(to) = event.to {
                    objects[index].class_changes.push((event.at_s, to));
                    objects[index]
                        .class_changes
                        .sort_by(|a, b| a.0.total_cmp(&b.0));
                }
            }
            EventKind::RemoveLifejacket => {
                let Some(state) = objects[index].at(event.at_s) else {
                    continue;
                };
                objects[index].lifejacket_until_s = event.at_s;
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                rng.set_stream(stream);
                stream += 1;
                let id = objects.len() as u32 + 1;
                let steps = ((scenario.duration_s + 2.0 - event.at_s).max(0.0) / OBJECT_DT_S).ceil()
                    as usize
                    + 1;
                // The jacket floats off beside the swimmer and drifts with the current.
                let start = [state.pos_ned_m[0] + 0.4, state.pos_ned_m[1] + 0.2];
                let track = drift(start, [0.0, 0.1], current, 0.1, steps, &mut rng);
                objects.push(SimObject {
                    id,
                    initial_class: ObjectClass::LifeSavingAppliance,
                    class_changes: Vec::new(),
                    lifejacket_until_s: f64::NEG_INFINITY,
                    appears_s: event.at_s,
                    length_m: 0.6,
                    width_m: 0.45,
                    height_m: 0.15,
                    palette: objects[index].palette,
                    track,
                });
            }
        }
    }
    objects
}

fn spawn(
    group: &ObjectGroup,
    id: u32,
    current: [f64; 2],
    n_steps: usize,
    rng: &mut ChaCha8Rng,
) -> SimObject {
    let r = group.spawn_radius_m * rng.random::<f64>().sqrt();
    let a = rng.random_range(0.0..std::f64::consts::TAU);
    let start = [
        group.spawn_center_ne_m[0] + r * a.cos(),
        group.spawn_center_ne_m[1] + r * a.sin(),
    ];
    let [lo, hi] = group
        .speed_mps
        .unwrap_or_else(|| default_speed_range(group.class));
    let speed = if hi > lo {
        rng.random_range(lo..=hi)
    } else {
        lo
    };
    let heading = match group.heading_deg {
        Some(h) => (h + group.heading_spread_deg * rng.random_range(-1.0..=1.0)).to_radians(),
        None => rng.random_range(0.0..std::f64::consts::TAU),
    };
    let (mut length, mut width, height) = draw_size(group.class, rng);
    if let Some([l, w]) = group.size_m {
        length = l;
        width = w;
    }
    let palette = rng.random_range(0..8);
    let walk = group.random_walk;
    let track = match group.class {
        ObjectClass::Swimmer => swim(start, speed, heading, hi, walk, current, n_steps, rng),
        ObjectClass::Boat | ObjectClass::Jetski => {
            let turn_sigma = if group.class == ObjectClass::Jetski {
                30.0
            } else {
                12.0
            };
            cruise(
                start,
                speed,
                heading,
                [lo, hi],
                walk,
                turn_sigma,
                n_steps,
                rng,
            )
        }
        ObjectClass::LifeSavingAppliance => {
            let v = [speed * heading.cos(), speed * heading.sin()];
            drift(start, v, current, walk * 0.3, n_steps, rng)
        }
        ObjectClass::Buoy => vec![[start[0], start[1], heading]; n_steps],
    };
    SimObject {
        id,
        initial_class: group.class,
        class_changes: Vec::new(),
        lifejacket_until_s: if group.lifejacket {
            f64::INFINITY
        } else {
            f64::NEG_INFINITY
        },
        appears_s: 0.0,
        length_m: length,
        width_m: width,
        height_m: height,
        palette,
        track,
    }
}

fn normal(rng: &mut ChaCha8Rng) -> f64 {
    StandardNormal.sample(rng)
}

/// Swimmer: an Ornstein-Uhlenbeck velocity around a slowly wandering mean, speed capped at
/// `max_speed`, plus the current. Facing follows the swimming direction.
#[allow(clippy::too_many_arguments)]
fn swim(
    start: [f64; 2],
    speed: f64,
    heading: f64,
    max_speed: f64,
    walk: f64,
    current: [f64; 2],
    n: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<[f64; 3]> {
    let dt = OBJECT_DT_S;
    let tau_s = 4.0;
    let mut p = start;
    let mut mean_heading = heading;
    let mut v = [speed * heading.cos(), speed * heading.sin()];
    let mut facing = heading;
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        out.push([p[0], p[1], facing]);
        mean_heading += walk * 0.5 * dt.sqrt() * normal(rng);
        let target = [speed * mean_heading.cos(), speed * mean_heading.sin()];
        let sigma = walk * 0.4;
        for k in 0..2 {
            v[k] += (target[k] - v[k]) * dt / tau_s + sigma * dt.sqrt() * normal(rng);
        }
        let s = v[0].hypot(v[1]);
        let cap = max_speed.max(0.05);
        if s > cap {
            v = [v[0] * cap / s, v[1] * cap / s];
        }
        if s > 0.05 {
            let want = v[1].atan2(v[0]);
            facing += crate::motion::wrap_180((want - facing).to_degrees()).to_radians() * 0.1;
        }
        p = [
            p[0] + (v[0] + current[0]) * dt,
            p[1] + (v[1] + current[1]) * dt,
        ];
    }
    out
}

/// Boat / jetski: speed wanders within its range; heading turns with a noisy turn rate and
/// occasional deliberate turns of 45-135 degrees.
#[allow(clippy::too_many_arguments)]
fn cruise(
    start: [f64; 2],
    speed: f64,
    heading: f64,
    range: [f64; 2],
    walk: f64,
    turn_sigma_deg_s: f64,
    n: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<[f64; 3]> {
    let dt = OBJECT_DT_S;
    let mut p = start;
    let mut h = heading;
    let mut s = speed;
    let mut turn_rate = 0.0_f64;
    let mut turn_left_rad = 0.0_f64;
    let mut out = Vec::with_capacity(n);
    // Mean time between deliberate turns shrinks with the random-walk strength.
    let turn_prob = (walk * dt / 20.0).min(1.0);
    for _ in 0..n {
        out.push([p[0], p[1], h]);
        if turn_left_rad.abs() < 1e-6 && rng.random::<f64>() < turn_prob {
            let mag = rng.random_range(45.0_f64..135.0).to_radians();
            turn_left_rad = if rng.random::<bool>() { mag } else { -mag };
        }
        let deliberate = if turn_left_rad.abs() > 1e-6 {
            let step =
                (20.0_f64.to_radians() * dt).min(turn_left_rad.abs()) * turn_left_rad.signum();
            turn_left_rad -= step;
            step
        } else {
            0.0
        };
        turn_rate +=
            -turn_rate * dt / 3.0 + walk * turn_sigma_deg_s.to_radians() * dt.sqrt() * normal(rng);
        h += turn_rate * dt + deliberate;
        s += (speed - s) * dt / 10.0 + walk * 0.5 * dt.sqrt() * normal(rng);
        s = s.clamp(range[0], range[1].max(range[0]));
        p = [p[0] + s * h.cos() * dt, p[1] + s * h.sin() * dt];
    }
    out
}

/// Floating object: own velocity plus current plus a small random walk.
fn drift(
    start: [f64; 2],
    v0: [f64; 2],
    current: [f64; 2],
    walk: f64,
    n: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<[f64; 3]> {
    let dt = OBJECT_DT_S;
    let mut p = start;
    let mut v = v0;
    let mut h = 0.0_f64;
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        out.push([p[0], p[1], h]);
        for vk in &mut v {
            *vk += -*vk * dt / 10.0 + walk * dt.sqrt() * normal(rng);
        }
        h += 0.05 * dt.sqrt() * normal(rng);
        p = [
            p[0] + (v[0] + current[0]) * dt,
            p[1] + (v[1] + current[1]) * dt,
        ];
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn swimmers_stay_within_speed_and_boats_within_range() {
        let s = Scenario::load("mixed_mission_soak").unwrap();
        let objs = generate(&s, s.seed);
        for o in &objs {
            let mut t = 0.0;
            while t < 100.0 {
                if let Some(st) = o.at(t) {
                    match st.class {
                        ObjectClass::Swimmer => {
                            // Swimming speed <= 1 m/s plus the current (<= 0.12 m/s here).
                            assert!(st.speed_mps <= 1.0 + 0.12 + 1e-9, "{}", st.speed_mps)
                        }
                        ObjectClass::Boat => {
                            assert!(st.speed_mps >= 2.0 - 1e-9 && st.speed_mps <= 12.0 + 1e-9)
                        }
                        ObjectClass::Buoy => assert_eq!(st.speed_mps, 0.0),
                        _ => {}
                    }
                }
                t += 0.35;
            }
        }
    }

    #[test]
    fn remove_lifejacket_spawns_an_appliance() {
        let s = Scenario::load("swimmer_group").unwrap();
        let objs = generate(&s, s.seed);
        assert_eq!(objs.len(), 7);
        let swimmer = &objs[0];
        assert!(swimmer.at(19.9).unwrap().lifejacket);
        assert!(!swimmer.at(20.1).unwrap().lifejacket);
        let jacket = &objs[6];
        assert_eq!(jacket.id, 7);
        assert!(jacket.at(19.9).is_none());
        let j = jacket.at(20.0).unwrap();
        assert_eq!(j.class, ObjectClass::LifeSavingAppliance);
        let sw = swimmer.at(20.0).unwrap();
        let d = (j.pos_ned_m[0] - sw.pos_ned_m[0]).hypot(j.pos_ned_m[1] - sw.pos_ned_m[1]);
        assert!(d < 1.0, "{d}");
    }

    #[test]
    fn same_seed_same_paths_other_seed_differs() {
        let s = Scenario::load("calm_baseline").unwrap();
        let a = generate(&s, 5);
        let b = generate(&s, 5);
        let c = generate(&s, 6);
        assert_eq!(a[0].at(30.0), b[0].at(30.0));
        assert_ne!(a[0].at(30.0), c[0].at(30.0));
    }
}
