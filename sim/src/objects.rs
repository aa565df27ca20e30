//! Objects on the water: spawning, motion (random walks, boat turns, drift with the current
//! and the wind), timed class changes, stops and resumes, precomputed per object at
//! [`OBJECT_DT_S`] and interpolated.

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

/// Leeway of a class: the fraction of the wind speed (at 10 m) at which an object adrift
/// moves downwind through the water, on top of the current.
///
/// Orders of magnitude from the leeway tables of IAMSAR Vol. II (after Allen & Plourde,
/// 1999), reduced to a single downwind factor: these are approximations (the real leeway
/// has an offset, a crosswind component that makes drift diverge, and a spread), enough to
/// separate classes that drift apart over minutes.
///
/// - swimmer (person in water, with or without a life jacket): 0.015 (tables: about
///   0.01-0.02);
/// - boat and jetski, only while stopped (a `stop` event): 0.04 (small craft adrift: about
///   0.03-0.07); under way they hold their course over ground and neither wind nor current
///   moves them;
/// - life-saving appliance (life ring, jacket, small raft): 0.035 (life rafts without a
///   drogue: about 0.03-0.045);
/// - buoy: 0, the simulated buoys are moored (the current does not move them either).
pub fn leeway_fraction(class: ObjectClass) -> f64 {
    match class {
        ObjectClass::Swimmer => 0.015,
        ObjectClass::Boat | ObjectClass::Jetski => 0.04,
        ObjectClass::LifeSavingAppliance => 0.035,
        ObjectClass::Buoy => 0.0,
    }
}

/// Velocity over ground `[north, east]` of an object adrift: the current plus the leeway
/// `fraction` of the wind. With no wind it is exactly the current.
pub fn adrift_velocity(current_ne_mps: [f64; 2], wind_ne_mps: [f64; 2], fraction: f64) -> [f64; 2] {
    [
        current_ne_mps[0] + fraction * wind_ne_mps[0],
        current_ne_mps[1] + fraction * wind_ne_mps[1],
    ]
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
    let wind = scenario.sea.wind_ne_mps;
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
            let adrift = adrift_velocity(current, wind, leeway_fraction(group.class));
            objects.push(spawn(group, id, adrift, n_steps, &mut rng));
        }
    }
    apply_stops(scenario, &group_first_index, &mut objects);
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
            // Applied to the tracks above.
            EventKind::Stop | EventKind::Resume => {}
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
                // The jacket floats off beside the swimmer and drifts with the current and the wind.
                let start = [state.pos_ned_m[0] + 0.4, state.pos_ned_m[1] + 0.2];
                let adrift = adrift_velocity(
                    current,
                    wind,
                    leeway_fraction(ObjectClass::LifeSavingAppliance),
                );
                let track = drift(start, [0.0, 0.1], adrift, 0.1, steps, &mut rng);
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

/// Applies the `stop` and `resume` events to the tracks of the spawned objects.
fn apply_stops(scenario: &Scenario, group_first_index: &[usize], objects: &mut [SimObject]) {
    let sea = &scenario.sea;
    for (g, group) in scenario.objects.iter().enumerate() {
        let adrift = adrift_velocity(
            sea.current_ne_mps,
            sea.wind_ne_mps,
            leeway_fraction(group.class),
        );
        // The drift already in the spawned track: swimmers and appliances drift all along,
        // boats under way and buoys do not.
        let baked = match group.class {
            ObjectClass::Swimmer | ObjectClass::LifeSavingAppliance => adrift,
            ObjectClass::Boat | ObjectClass::Jetski => [0.0, 0.0],
            // Moored; validation refuses stops of buoys.
            ObjectClass::Buoy => continue,
        };
        let Some(&first) = group_first_index.get(g) else {
            continue;
        };
        for member in 0..group.count {
            let mut switches: Vec<(f64, bool)> = scenario
                .events
                .iter()
                .filter(|e| e.group == g && e.member == member)
                .filter_map(|e| match e.kind {
                    EventKind::Stop => Some((e.at_s, true)),
                    EventKind::Resume => Some((e.at_s, false)),
                    _ => None,
                })
                .collect();
            if switches.is_empty() {
                continue;
            }
            switches.sort_by(|a, b| a.0.total_cmp(&b.0));
            if let Some(object) = objects.get_mut(first + member as usize) {
                let appears_s = object.appears_s;
                stop_and_resume(&mut object.track, appears_s, &switches, baked, adrift);
            }
        }
    }
}

/// Rewrites `track` (sampled from `appears_s`) for `switches` `(at_s, stop)`, in time
/// order: from a stop the object only drifts at `adrift` and keeps its heading; from a resume
/// it moves again as in the original track, rotated to continue on the heading it kept.
/// `baked` is the drift contained in the original track, which is not rotated.
fn stop_and_resume(
    track: &mut [[f64; 3]],
    appears_s: f64,
    switches: &[(f64, bool)],
    baked: [f64; 2],
    adrift: [f64; 2],
) {
    let original = track.to_vec();
    let dt = OBJECT_DT_S;
    let mut next = 0;
    let mut stopped = false;
    let mut touched = false;
    // Heading offset of the resumed motion from the original.
    let mut rotation = 0.0_f64;
    for k in 1..track.len() {
        let t_prev = appears_s + (k - 1) as f64 * dt;
        while let Some(&(at_s, stop)) = switches.get(next) {
            if at_s > t_prev {
                break;
            }
            next += 1;
            if stop && !stopped {
                stopped = true;
                touched = true;
            } else if !stop && stopped {
                stopped = false;
                rotation = track[k - 1][2] - original[k - 1][2];
            }
        }
        if !touched {
            continue;
        }
        let prev = track[k - 1];
        track[k] = if stopped {
            [prev[0] + adrift[0] * dt, prev[1] + adrift[1] * dt, prev[2]]
        } else {
            let own = [
                original[k][0] - original[k - 1][0] - baked[0] * dt,
                original[k][1] - original[k - 1][1] - baked[1] * dt,
            ];
            let (sin, cos) = rotation.sin_cos();
            [
                prev[0] + own[0] * cos - own[1] * sin + baked[0] * dt,
                prev[1] + own[0] * sin + own[1] * cos + baked[1] * dt,
                original[k][2] + rotation,
            ]
        };
    }
}

fn spawn(
    group: &ObjectGroup,
    id: u32,
    adrift: [f64; 2],
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
        ObjectClass::Swimmer => swim(start, speed, heading, hi, walk, adrift, n_steps, rng),
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
            drift(start, v, adrift, walk * 0.3, n_steps, rng)
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
/// `max_speed`, plus the drift `adrift` (current and leeway). Facing follows the swimming
/// direction.
#[allow(clippy::too_many_arguments)]
fn swim(
    start: [f64; 2],
    speed: f64,
    heading: f64,
    max_speed: f64,
    walk: f64,
    adrift: [f64; 2],
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
            p[0] + (v[0] + adrift[0]) * dt,
            p[1] + (v[1] + adrift[1]) * dt,
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

/// Floating object: own velocity plus the drift `adrift` (current and leeway) plus a small
/// random walk.
fn drift(
    start: [f64; 2],
    v0: [f64; 2],
    adrift: [f64; 2],
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
            p[0] + (v[0] + adrift[0]) * dt,
            p[1] + (v[1] + adrift[1]) * dt,
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

    /// With wind, everything adrift moves downwind by its leeway on top of its own motion
    /// (same seed, so the own motion is the same); boats under way and buoys do not.
    #[test]
    fn wind_adds_leeway_per_class() {
        let calm = Scenario::load("calm_baseline").unwrap();
        let mut windy = calm.clone();
        windy.sea.wind_ne_mps = [0.0, 10.0];
        let (a, b) = (generate(&calm, 3), generate(&windy, 3));
        let t = 30.0;
        for (oa, ob) in a.iter().zip(&b) {
            let (pa, pb) = (oa.at(t).unwrap(), ob.at(t).unwrap());
            let de = pb.pos_ned_m[1] - pa.pos_ned_m[1];
            let dn = pb.pos_ned_m[0] - pa.pos_ned_m[0];
            let want = match pa.class {
                ObjectClass::Swimmer => 0.015 * 10.0 * t,
                ObjectClass::LifeSavingAppliance => 0.035 * 10.0 * t,
                ObjectClass::Boat | ObjectClass::Jetski | ObjectClass::Buoy => 0.0,
            };
            // Sampled at OBJECT_DT_S: the drift up to the sample before t, plus a fraction.
            assert!((de - want).abs() < 1e-6, "{:?}: {de} vs {want}", pa.class);
            assert!(dn.abs() < 1e-9, "{dn}");
        }
    }

    /// A boat that stops only drifts (current + 4 % of the wind) on its heading, and
    /// resumes at its own speed on that heading.
    #[test]
    fn a_stopped_boat_drifts_and_resumes() {
        use crate::scenario::{Event, EventKind};
        let mut s = Scenario::load("calm_baseline").unwrap();
        s.sea.current_ne_mps = [0.1, 0.0];
        s.sea.wind_ne_mps = [0.0, 5.0];
        let boat = s
            .objects
            .iter()
            .position(|g| g.class == ObjectClass::Boat)
            .unwrap();
        let before = generate(&s, s.seed);
        for (kind, at_s) in [(EventKind::Stop, 10.0), (EventKind::Resume, 20.0)] {
            s.events.push(Event {
                kind,
                group: boat,
                member: 0,
                at_s,
                to: None,
            });
        }
        s.validate("t").unwrap();
        let after = generate(&s, s.seed);
        let id = before
            .iter()
            .position(|o| o.initial_class == ObjectClass::Boat)
            .unwrap();
        let (b, o) = (&before[id], &after[id]);
        for t in [0.0, 5.0, 9.95] {
            assert_eq!(b.at(t), o.at(t), "t={t}");
        }
        let (p12, p18) = (o.at(12.0).unwrap(), o.at(18.0).unwrap());
        let drift = [0.1, 0.04 * 5.0];
        assert!((p18.pos_ned_m[0] - p12.pos_ned_m[0] - drift[0] * 6.0).abs() < 1e-9);
        assert!((p18.pos_ned_m[1] - p12.pos_ned_m[1] - drift[1] * 6.0).abs() < 1e-9);
        assert!((p12.speed_mps - drift[0].hypot(drift[1])).abs() < 1e-9);
        assert_eq!(p12.heading_rad, p18.heading_rad);
        // Under way again, at its own speed (2-3 m/s here), leaving on the kept heading.
        let p = o.at(20.15).unwrap();
        assert!((2.0..=3.0 + 1e-9).contains(&p.speed_mps), "{}", p.speed_mps);
        assert!((p.heading_rad - p18.heading_rad).abs() < 0.1);
        // The other objects are untouched.
        for (x, y) in before.iter().zip(&after) {
            if x.id != b.id {
                assert_eq!(x.at(15.0), y.at(15.0));
            }
        }
    }

    /// A swimmer that stops swimming drifts with the current and its 1.5 % leeway.
    #[test]
    fn a_stopped_swimmer_only_drifts() {
        use crate::scenario::{Event, EventKind};
        let mut s = Scenario::load("calm_baseline").unwrap();
        s.sea.current_ne_mps = [0.0, -0.2];
        s.sea.wind_ne_mps = [8.0, 0.0];
        s.events.push(Event {
            kind: EventKind::Stop,
            group: 0,
            member: 1,
            at_s: 5.0,
            to: None,
        });
        let o = &generate(&s, s.seed)[1];
        let (a, b) = (o.at(10.0).unwrap(), o.at(40.0).unwrap());
        assert!((b.pos_ned_m[0] - a.pos_ned_m[0] - 0.015 * 8.0 * 30.0).abs() < 1e-9);
        assert!((b.pos_ned_m[1] - a.pos_ned_m[1] + 0.2 * 30.0).abs() < 1e-9);
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
