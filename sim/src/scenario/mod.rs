//! Scenario files: the TOML schema and loading with field-naming errors. Validation is in
//! `validate.rs` ([`Scenario::validate`]), the named scenarios shipped in `sim/scenarios/`
//! (embedded in the binary) in `shipped.rs` ([`SHIPPED`]).
//!
//! The schema is documented field by field in `sim/README.md`; every struct here denies
//! unknown fields so that a typo is an error that names the field rather than a silently
//! ignored setting.

mod shipped;
mod validate;

pub use shipped::SHIPPED;

use serde::Deserialize;
use std::path::Path;

/// Errors from loading or validating a scenario.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// The name is neither a shipped scenario nor an existing file.
    #[error("unknown scenario `{name}`: not a shipped scenario ({known}) and no such file")]
    Unknown {
        /// What the user asked for.
        name: String,
        /// The shipped names, comma separated.
        known: String,
    },
    /// The file could not be read.
    #[error("cannot read scenario file {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The TOML is malformed or does not match the schema (the message names the field
    /// and the line).
    #[error("invalid scenario {origin}: {message}")]
    Parse {
        /// File path or shipped name.
        origin: String,
        /// The parser's message, with line, column and field.
        message: String,
    },
    /// Fields have values outside their allowed ranges (every one found, in schema order).
    #[error(
        "invalid scenario {origin}: {}",
        .problems.iter().map(ToString::to_string).collect::<Vec<_>>().join("; ")
    )]
    Invalid {
        /// File path or shipped name.
        origin: String,
        /// Every problem found, never empty.
        problems: Vec<FieldProblem>,
    },
    /// `--vehicle K` names a vehicle the scenario does not have.
    #[error("scenario `{scenario}` has {count} vehicle(s) (0 to {}), not vehicle {vehicle}", .count - 1)]
    NoVehicle {
        /// The scenario.
        scenario: String,
        /// The vehicle asked for.
        vehicle: usize,
        /// How many it has (the top-level drone and `vehicles`).
        count: usize,
    },
}

/// One invalid field of a scenario.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("field `{field}`: {problem}")]
pub struct FieldProblem {
    /// Dotted path of the field, e.g. `camera.fps` or `objects[2].count`.
    pub field: String,
    /// What is wrong with it.
    pub problem: String,
}

/// A complete scenario.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Short name; used as the sequence name in ground truth (`source.folder_name`).
    pub name: String,
    /// One line saying what the scenario exercises.
    #[serde(default)]
    pub description: String,
    /// Seed of every random process; `--seed` overrides it.
    #[serde(default = "default_seed")]
    pub seed: u64,
    /// Length of the simulated flight.
    pub duration_s: f64,
    /// Where the local NED frame sits on the Earth.
    pub origin: Origin,
    /// The drone's path, speed and altitude.
    pub drone: Drone,
    /// The gimbal program.
    #[serde(default)]
    pub gimbal: Gimbal,
    /// The camera.
    #[serde(default)]
    pub camera: Camera,
    /// Sea state and lighting.
    #[serde(default)]
    pub sea: Sea,
    /// Groups of objects on the water.
    #[serde(default)]
    pub objects: Vec<ObjectGroup>,
    /// Timed changes to objects (class changes, life jackets, stops and resumes).
    #[serde(default)]
    pub events: Vec<Event>,
    /// Errors injected into the metadata the autopilot reports.
    #[serde(default)]
    pub faults: Faults,
    /// How the autopilot reports things.
    #[serde(default)]
    pub telemetry: Telemetry,
    /// Parameters of the detection simulator.
    #[serde(default)]
    pub detector: Detector,
    /// Switches and levels of the frame renderer's realism features.
    #[serde(default)]
    pub render: Render,
    /// More drones over the same water: the same seed, sea and objects (so the same truth),
    /// each with its own path, gimbal program, camera and MAVLink system id.
    /// `--vehicle K` flies the K-th of them (1-based; 0, the default, is the top-level
    /// `drone`); [`Scenario::for_vehicle`].
    #[serde(default)]
    pub vehicles: Vec<Vehicle>,
    /// Which of the scenario's vehicles this is (0: the top-level drone), set by
    /// [`Scenario::for_vehicle`]: each vehicle's own random processes (its telemetry's
    /// faults and jitter, its gimbal program, its detector's noise) draw from streams of
    /// their own ([`Scenario::vehicle_stream`]), as two real drones' GNSS receivers and
    /// cameras err independently.
    #[serde(skip)]
    pub vehicle: usize,
}

/// One more drone of a scenario with several ([`Scenario::vehicles`]).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Vehicle {
    /// Its MAVLink system id; every vehicle of the scenario has its own.
    pub system_id: u8,
    /// Its path, speed and altitude.
    pub drone: Drone,
    /// Its gimbal program; default: the scenario's.
    #[serde(default)]
    pub gimbal: Option<Gimbal>,
    /// Its camera; default: the scenario's.
    #[serde(default)]
    pub camera: Option<Camera>,
}

fn default_seed() -> u64 {
    1
}

/// The home position, which is also the origin of local NED and sits on the waterline.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Origin {
    /// Latitude of home.
    pub lat_deg: f64,
    /// Longitude of home.
    pub lon_deg: f64,
    /// Altitude of home (= water level) above mean sea level.
    #[serde(default)]
    pub alt_amsl_m: f64,
    /// UTC time of the start of the scenario, seconds since the Unix epoch (SYSTEM_TIME,
    /// `date_time` in the ground truth).
    #[serde(default = "default_start_unix")]
    pub start_unix_s: f64,
}

fn default_start_unix() -> f64 {
    // 2024-06-01T12:00:00Z
    1_717_243_200.0
}

/// The drone: path, speed and altitude profile.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Drone {
    /// Cruise speed over ground when no `speed_profile` is given.
    #[serde(default = "default_speed")]
    pub speed_mps: f64,
    /// Optional piecewise-linear speed profile: `[[t_s, speed_mps], ...]`.
    #[serde(default)]
    pub speed_profile: Vec<[f64; 2]>,
    /// Height above the water when no `altitude_profile` is given.
    #[serde(default = "default_altitude")]
    pub altitude_m: f64,
    /// Optional piecewise-linear altitude profile: `[[t_s, altitude_m], ...]`.
    #[serde(default)]
    pub altitude_profile: Vec<[f64; 2]>,
    /// Largest yaw rate of the vehicle; heading changes at corners are limited to it.
    #[serde(default = "default_yaw_rate")]
    pub max_yaw_rate_deg_s: f64,
    /// The horizontal path.
    pub path: Path2d,
}

fn default_speed() -> f64 {
    5.0
}
fn default_altitude() -> f64 {
    30.0
}
fn default_yaw_rate() -> f64 {
    60.0
}

/// The drone's horizontal path in local north/east metres.
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Path2d {
    /// Stay at one point, facing `heading_deg`.
    Hover {
        /// Position `[north_m, east_m]`.
        at_ne_m: [f64; 2],
        /// Vehicle heading.
        #[serde(default)]
        heading_deg: f64,
    },
    /// Fly a polyline; at its end, hover (or start over when `looped`).
    Waypoints {
        /// Points `[[north_m, east_m], ...]` (at least two).
        points_ne_m: Vec<[f64; 2]>,
        /// Return to the first point and repeat.
        #[serde(default)]
        looped: bool,
    },
    /// Circle a point.
    Loiter {
        /// Centre `[north_m, east_m]`.
        center_ne_m: [f64; 2],
        /// Radius of the circle.
        radius_m: f64,
        /// Direction seen from above.
        #[serde(default = "default_true")]
        clockwise: bool,
    },
    /// A lawnmower (boustrophedon) search pattern.
    Lawnmower {
        /// Start of the first leg `[north_m, east_m]`.
        start_ne_m: [f64; 2],
        /// Direction of the first leg.
        heading_deg: f64,
        /// Length of every leg.
        leg_length_m: f64,
        /// Distance between legs (to the right of the first leg's direction).
        spacing_m: f64,
        /// Number of legs.
        legs: u32,
    },
    /// An IAMSAR expanding square search from a datum: legs of 1, 1, 2, 2, 3, 3, ... times
    /// the track spacing, turning 90 degrees after each.
    ExpandingSquare {
        /// The datum `[north_m, east_m]`, where the first leg starts.
        datum_ne_m: [f64; 2],
        /// Direction of the first leg.
        first_heading_deg: f64,
        /// Track spacing: the length of the first two legs and the growth of the others.
        spacing_m: f64,
        /// Number of legs.
        legs: u32,
        /// Turn right after each leg (left when false).
        #[serde(default = "default_true")]
        clockwise: bool,
    },
    /// An IAMSAR sector search ("VS"): three equilateral triangles of side `radius_m` with
    /// a corner on the datum, turning 120 degrees at the outer corners and flying straight
    /// on through the datum into the next triangle (nine legs of `radius_m` per pattern);
    /// pattern `k` is the first rotated `30 * k` degrees in the turning direction.
    Sector {
        /// The datum `[north_m, east_m]`, where the pattern starts and which every triangle
        /// passes.
        datum_ne_m: [f64; 2],
        /// Length of every leg (the radius of the searched circle).
        radius_m: f64,
        /// Direction of the first leg.
        first_heading_deg: f64,
        /// Number of patterns (IAMSAR flies one, or two with the second rotated 30 deg).
        #[serde(default = "default_patterns")]
        patterns: u32,
        /// Turn right (120 degrees) after each leg (left when false).
        #[serde(default = "default_true")]
        clockwise: bool,
    },
}

fn default_patterns() -> u32 {
    1
}

fn default_true() -> bool {
    true
}

/// Which way a yaw angle is referenced.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "snake_case")]
pub enum YawFrame {
    /// Relative to the vehicle's heading (gimbal "follow" mode).
    #[default]
    Vehicle,
    /// Relative to north (gimbal "lock" mode).
    Earth,
}

/// The gimbal program. Pitch is degrees below the horizon (90 = nadir), stabilised.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Gimbal {
    /// `fixed`, `sweep` (slow sinusoidal pan) or `swings` (sudden jumps at high rate).
    pub mode: GimbalMode,
    /// Mean pitch below the horizon.
    pub pitch_deg: f64,
    /// Mean yaw, relative to the vehicle or to north per `yaw_reference`.
    pub yaw_deg: f64,
    /// How the gimbal holds yaw.
    pub yaw_reference: YawFrame,
    /// Sweep: yaw amplitude either side of `yaw_deg`.
    pub sweep_yaw_amplitude_deg: f64,
    /// Sweep: pitch amplitude either side of `pitch_deg`.
    pub sweep_pitch_amplitude_deg: f64,
    /// Sweep: period of one full back-and-forth.
    pub sweep_period_s: f64,
    /// Swings: seconds between sudden moves.
    pub swing_interval_s: f64,
    /// Swings: largest yaw offset of a move target.
    pub swing_yaw_amplitude_deg: f64,
    /// Swings: largest pitch offset of a move target.
    pub swing_pitch_amplitude_deg: f64,
    /// Swings: slew rate while moving.
    pub swing_rate_deg_s: f64,
}

impl Default for Gimbal {
    fn default() -> Self {
        Self {
            mode: GimbalMode::Fixed,
            pitch_deg: 45.0,
            yaw_deg: 0.0,
            yaw_reference: YawFrame::Vehicle,
            sweep_yaw_amplitude_deg: 30.0,
            sweep_pitch_amplitude_deg: 0.0,
            sweep_period_s: 40.0,
            swing_interval_s: 6.0,
            swing_yaw_amplitude_deg: 60.0,
            swing_pitch_amplitude_deg: 15.0,
            swing_rate_deg_s: 150.0,
        }
    }
}

/// Gimbal program kinds.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum GimbalMode {
    /// Hold `pitch_deg` / `yaw_deg`.
    Fixed,
    /// Sinusoidal pan (and optionally tilt).
    Sweep,
    /// Hold, then jump to a random offset at `swing_rate_deg_s`, repeatedly.
    Swings,
}

/// The camera (pinhole, no distortion; intrinsics from the horizontal FOV).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Camera {
    /// Image width.
    pub width_px: u32,
    /// Image height.
    pub height_px: u32,
    /// Horizontal field of view.
    pub hfov_deg: f64,
    /// Frame rate.
    pub fps: f64,
    /// Time from exposure to the frame being available to the consumer.
    pub capture_latency_ms: f64,
}

impl Default for Camera {
    fn default() -> Self {
        Self {
            width_px: 1280,
            height_px: 720,
            hfov_deg: 70.0,
            fps: 30.0,
            capture_latency_ms: 40.0,
        }
    }
}

/// Switches and levels of the frame renderer (`[render]`): every feature is on at a
/// realistic level by default; turn them off to get clean, synthetic-looking frames.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Render {
    /// Per-object variants (hull shapes, swimmer poses, buoy kinds, ring bands); off: one
    /// look per class.
    pub object_variety: bool,
    /// Sun-side / shadow-side shading, highlights and waterline shadows of objects.
    pub object_shading: bool,
    /// Foam wakes behind moving boats and jetskis.
    pub wakes: bool,
    /// Whitecaps and foam streaks, growing with `sea.wave_height_m` (none below ~0.45 m).
    pub whitecaps: bool,
    /// Sky reflection on the water by the Fresnel law (more sky towards the horizon).
    pub sky_reflection: bool,
    /// Large-scale colour variation of the water (patches of bluer / greener / greyer sea).
    pub color_variation: bool,
    /// Sensor noise level, 0 (none) to 2.5; 1: a typical small drone camera in daylight.
    pub camera_noise: f64,
    /// Slow, seeded exposure and white-balance drift.
    pub exposure_drift: bool,
    /// Darkening towards the corners, 0 (none) to 1 (strong).
    pub vignetting: f64,
    /// Slight lens blur (a 3x3 kernel over the whole frame).
    pub defocus: bool,
    /// Motion blur along the image motion of the sea during the exposure (from the drone's
    /// and the gimbal's rates); only in frames rendered from the scenario's own flight.
    pub motion_blur: bool,
    /// Exposure time used for the motion blur, seconds.
    pub exposure_s: f64,
    /// JPEG quality of `mgmot-sim render --format jpg`, 1 to 100.
    pub jpeg_quality: u8,
}

impl Default for Render {
    fn default() -> Self {
        Self {
            object_variety: true,
            object_shading: true,
            wakes: true,
            whitecaps: true,
            sky_reflection: true,
            color_variation: true,
            camera_noise: 1.0,
            exposure_drift: true,
            vignetting: 0.25,
            defocus: true,
            motion_blur: true,
            exposure_s: 1.0 / 250.0,
            jpeg_quality: 85,
        }
    }
}

impl Render {
    /// Every realism feature off: flat objects, plain sea, no camera effects (quality 90).
    pub fn off() -> Render {
        Render {
            object_variety: false,
            object_shading: false,
            wakes: false,
            whitecaps: false,
            sky_reflection: false,
            color_variation: false,
            camera_noise: 0.0,
            exposure_drift: false,
            vignetting: 0.0,
            defocus: false,
            motion_blur: false,
            exposure_s: 1.0 / 250.0,
            jpeg_quality: 90,
        }
    }
}

/// Sea state and lighting.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Sea {
    /// Wave contrast, 0 (flat) to about 2 (rough).
    pub wave_height_m: f64,
    /// Dominant wavelength.
    pub wave_length_m: f64,
    /// Direction the waves travel towards (bearing).
    pub wave_direction_deg: f64,
    /// Phase speed of the waves.
    pub wave_speed_mps: f64,
    /// Sun elevation above the horizon.
    pub sun_elevation_deg: f64,
    /// Sun bearing.
    pub sun_azimuth_deg: f64,
    /// Strength of sun glint, 0 to 1.
    pub glint: f64,
    /// Surface current `[north, east]` carrying everything adrift: swimmers, appliances and
    /// stopped boats (boats under way and the moored buoys are not carried).
    pub current_ne_mps: [f64; 2],
    /// Wind at 10 m `[north, east]` (the direction it blows *towards*): objects adrift also
    /// move downwind at their class's leeway fraction of it
    /// ([`crate::objects::leeway_fraction`]). Default calm.
    pub wind_ne_mps: [f64; 2],
    /// Base sea colour, RGB.
    pub color_rgb: [u8; 3],
}

impl Default for Sea {
    fn default() -> Self {
        Self {
            wave_height_m: 0.5,
            wave_length_m: 6.0,
            wave_direction_deg: 60.0,
            wave_speed_mps: 1.5,
            sun_elevation_deg: 45.0,
            sun_azimuth_deg: 180.0,
            glint: 0.6,
            current_ne_mps: [0.0, 0.0],
            wind_ne_mps: [0.0, 0.0],
            color_rgb: [22, 70, 92],
        }
    }
}

/// Object classes, with the SeaDronesSee category ids.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[serde(rename_all = "snake_case")]
pub enum ObjectClass {
    /// A person in the water (category 1).
    Swimmer,
    /// A boat (category 2).
    Boat,
    /// A jetski (category 3).
    Jetski,
    /// A life ring, life jacket or raft on its own (category 4).
    LifeSavingAppliance,
    /// A buoy (category 5).
    Buoy,
}

impl ObjectClass {
    /// Every class, in SeaDronesSee category order.
    pub const ALL: [ObjectClass; 5] = [
        ObjectClass::Swimmer,
        ObjectClass::Boat,
        ObjectClass::Jetski,
        ObjectClass::LifeSavingAppliance,
        ObjectClass::Buoy,
    ];

    /// The class of a SeaDronesSee / COCO category id, if it is one.
    pub fn from_category_id(id: u32) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.category_id() == id)
    }

    /// The SeaDronesSee / COCO category id.
    pub fn category_id(self) -> u32 {
        match self {
            ObjectClass::Swimmer => 1,
            ObjectClass::Boat => 2,
            ObjectClass::Jetski => 3,
            ObjectClass::LifeSavingAppliance => 4,
            ObjectClass::Buoy => 5,
        }
    }

    /// The SeaDronesSee category name.
    pub fn name(self) -> &'static str {
        match self {
            ObjectClass::Swimmer => "swimmer",
            ObjectClass::Boat => "boat",
            ObjectClass::Jetski => "jetski",
            ObjectClass::LifeSavingAppliance => "life_saving_appliances",
            ObjectClass::Buoy => "buoy",
        }
    }
}

/// A group of objects of one class spawned in one area.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectGroup {
    /// Their class.
    pub class: ObjectClass,
    /// How many.
    #[serde(default = "default_count")]
    pub count: u32,
    /// Centre of the spawn disc `[north_m, east_m]`.
    pub spawn_center_ne_m: [f64; 2],
    /// Radius of the spawn disc (uniform).
    #[serde(default = "default_spawn_radius")]
    pub spawn_radius_m: f64,
    /// Speed range `[min, max]` through the water; each object draws its mean speed from it.
    /// Defaults per class: swimmer 0-1, boat 2-12, jetski 5-15, appliance 0-0.3, buoy 0.
    #[serde(default)]
    pub speed_mps: Option<[f64; 2]>,
    /// Common heading; absent means a random heading per object.
    #[serde(default)]
    pub heading_deg: Option<f64>,
    /// Spread of headings around `heading_deg` (uniform, either side).
    #[serde(default)]
    pub heading_spread_deg: f64,
    /// Random-walk strength, 0 (straight lines) to about 1 (erratic). Swimmers: velocity
    /// noise; boats: turn-rate noise.
    #[serde(default = "default_random_walk")]
    pub random_walk: f64,
    /// Swimmers only: wearing a colourful life jacket at the start.
    #[serde(default = "default_true")]
    pub lifejacket: bool,
    /// Optional size `[length_m, width_m]` override (defaults per class; boats draw a
    /// random length of 5-12 m).
    #[serde(default)]
    pub size_m: Option<[f64; 2]>,
}

fn default_count() -> u32 {
    1
}
fn default_spawn_radius() -> f64 {
    20.0
}
fn default_random_walk() -> f64 {
    0.3
}

/// A timed change to one object.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Event {
    /// What happens.
    pub kind: EventKind,
    /// Index of the object group in `objects`.
    pub group: usize,
    /// Index of the object within the group.
    #[serde(default)]
    pub member: u32,
    /// When.
    pub at_s: f64,
    /// For `change_class`: the new class.
    #[serde(default)]
    pub to: Option<ObjectClass>,
}

/// Kinds of events.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum EventKind {
    /// A swimmer takes off the life jacket: the swimmer loses the colourful vest and a new
    /// `life_saving_appliance` object (with its own id) appears there and drifts away.
    RemoveLifejacket,
    /// The object's class changes to `to` (same id).
    ChangeClass,
    /// The object stops under its own power (a boat stops its engine among swimmers, a
    /// swimmer stops swimming): its speed through the water becomes 0 and it only drifts
    /// with the current and its leeway in the wind, keeping its heading. Not for buoys.
    Stop,
    /// A stopped object moves under its own power again, on the heading it kept while
    /// stopped. Needs an earlier `stop` of the same object.
    Resume,
}

/// Metadata faults: what the autopilot reports differs from the truth by these.
#[derive(Debug, Clone, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct Faults {
    /// Constant bias of the vehicle attitude `[roll, pitch, yaw]`.
    pub attitude_bias_deg: [f64; 3],
    /// White noise (1 sigma) on each vehicle attitude angle.
    pub attitude_noise_deg: f64,
    /// Constant bias of the reported gimbal pitch (positive: reported further below the
    /// horizon than the truth).
    pub gimbal_pitch_bias_deg: f64,
    /// Constant bias of the reported gimbal yaw.
    pub gimbal_yaw_bias_deg: f64,
    /// White noise (1 sigma) on the reported gimbal angles.
    pub gimbal_noise_deg: f64,
    /// GPS horizontal noise (1 sigma, slowly varying: first-order Gauss-Markov, 5 s).
    pub gps_noise_m: f64,
    /// Constant bias of the reported altitude (positive: reported higher).
    pub altitude_bias_m: f64,
    /// Telemetry messages describe the state this long before they are sent.
    pub telemetry_latency_ms: f64,
    /// Frame timestamps are this much later than the true capture time (camera vs
    /// telemetry clock desync).
    pub camera_time_offset_ms: f64,
    /// Windows `[[start_s, duration_s], ...]` in which the autopilot sends nothing.
    pub dropouts: Vec<[f64; 2]>,
    /// Times (s) at which the autopilot reboots: it is silent for
    /// [`crate::world::REBOOT_SILENCE_S`], its `time_boot_ms` starts again from there, and it
    /// forgets every SET_MESSAGE_INTERVAL.
    pub reboots_s: Vec<f64>,
    /// A ground station also answers every TIMESYNC request (the autopilot forwards mgmot's
    /// requests to it and its answers back), from system 255 with its own clock.
    pub gcs_timesync_answers: bool,
}

/// How the autopilot reports.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Telemetry {
    /// Frame of the yaw in GIMBAL_DEVICE_ATTITUDE_STATUS (flags YAW_IN_EARTH_FRAME or
    /// YAW_IN_VEHICLE_FRAME).
    pub gimbal_yaw_frame: YawFrame,
    /// Relative jitter of message intervals (uniform, either side).
    pub rate_jitter: f64,
    /// The autopilot's `time_boot_ms` at the start of the scenario.
    pub boot_time_s: f64,
    /// MAVLink system id of the simulated vehicle.
    pub system_id: u8,
    /// Whose habits the simulated autopilot has.
    pub autopilot: AutopilotKind,
    /// What the gimbal's attitude report means.
    pub gimbal_report: GimbalReport,
}

impl Default for Telemetry {
    fn default() -> Self {
        Self {
            gimbal_yaw_frame: YawFrame::Earth,
            rate_jitter: 0.05,
            boot_time_s: 120.0,
            system_id: 1,
            autopilot: AutopilotKind::Generic,
            gimbal_report: GimbalReport::AsFlagged,
        }
    }
}

/// The habits of the simulated autopilot.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "snake_case")]
pub enum AutopilotKind {
    /// Every stream at its default rate from the start; every message the simulator knows is
    /// sent, GIMBAL_DEVICE_ATTITUDE_STATUS from a gimbal component (154).
    #[default]
    Generic,
    /// As ArduCopter (upstream 90700977c5, seen in its SITL): only HEARTBEAT until a stream
    /// is asked for (the default stream rates are 0, and every request is forgotten at a
    /// reboot); MOUNT_ORIENTATION is refused (DENIED) and never sent;
    /// GIMBAL_DEVICE_ATTITUDE_STATUS comes from the autopilot's own component (1) with
    /// gimbal device id 1.
    Ardupilot,
}

/// What the gimbal's attitude report (GIMBAL_DEVICE_ATTITUDE_STATUS) means.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "snake_case")]
pub enum GimbalReport {
    /// What its flags say (`gimbal_yaw_frame`): a stabilised gimbal reporting its attitude.
    #[default]
    AsFlagged,
    /// As ArduPilot's servo mount (MNT1_TYPE 1): the servo angles after the autopilot's own
    /// lean compensation, i.e. relative to the vehicle body, while the flags still claim
    /// earth-frame roll and pitch and a vehicle-frame yaw.
    ServoBodyFrame,
}

/// Detection simulator parameters.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Detector {
    /// Box size (sqrt of area, px) at which half the objects are missed.
    pub miss_half_size_px: f64,
    /// Miss probability of large, clear objects.
    pub miss_floor: f64,
    /// Box jitter, 1 sigma, as a fraction of the box size.
    pub jitter_fraction: f64,
    /// Mean false positives per frame (glint and wave crests).
    pub false_positives_per_frame: f64,
    /// Detections below this score are not emitted.
    pub min_score: f64,
}

impl Default for Detector {
    fn default() -> Self {
        Self {
            miss_half_size_px: 6.0,
            miss_floor: 0.03,
            jitter_fraction: 0.06,
            false_positives_per_frame: 0.3,
            min_score: 0.05,
        }
    }
}

impl Scenario {
    /// Resolves `name_or_path`: a shipped name first, else a file path.
    pub fn load(name_or_path: &str) -> Result<Scenario, ScenarioError> {
        if let Some((name, text)) = SHIPPED.iter().find(|(n, _)| *n == name_or_path) {
            return Scenario::from_toml(text, &format!("`{name}` (shipped)"));
        }
        let path = Path::new(name_or_path);
        if !path.exists() {
            return Err(ScenarioError::Unknown {
                name: name_or_path.to_string(),
                known: SHIPPED
                    .iter()
                    .map(|(n, _)| *n)
                    .collect::<Vec<_>>()
                    .join(", "),
            });
        }
        let text = std::fs::read_to_string(path).map_err(|source| ScenarioError::Io {
            path: path.display().to_string(),
            source,
        })?;
        Scenario::from_toml(&text, &path.display().to_string())
    }

    /// Parses and validates TOML text; `origin` names the source in errors.
    pub fn from_toml(text: &str, origin: &str) -> Result<Scenario, ScenarioError> {
        let scenario: Scenario = toml::from_str(text).map_err(|e| ScenarioError::Parse {
            origin: origin.to_string(),
            message: e.to_string().trim_end().to_string(),
        })?;
        scenario.validate(origin)?;
        Ok(scenario)
    }

    /// The scenario as vehicle `k` flies it: 0 is the top-level drone (the scenario itself);
    /// `k >= 1` takes `vehicles[k - 1]`'s path, gimbal, camera and system id. The world (seed,
    /// sea, objects, events) is the same for all, and so is the truth. The result has no
    /// vehicles of its own.
    pub fn for_vehicle(&self, k: usize) -> Result<Scenario, ScenarioError> {
        let mut s = self.clone();
        s.vehicles.clear();
        if k == 0 {
            return Ok(s);
        }
        let v = self
            .vehicles
            .get(k - 1)
            .ok_or_else(|| ScenarioError::NoVehicle {
                scenario: self.name.clone(),
                vehicle: k,
                count: self.vehicles.len() + 1,
            })?;
        s.drone = v.drone.clone();
        if let Some(g) = &v.gimbal {
            s.gimbal = g.clone();
        }
        if let Some(c) = &v.camera {
            s.camera = c.clone();
        }
        s.telemetry.system_id = v.system_id;
        s.vehicle = k;
        Ok(s)
    }

    /// The random stream `stream` as this vehicle draws it: the stream itself for vehicle 0
    /// (so a one-drone scenario is unchanged), a stream of its own for each other vehicle.
    pub fn vehicle_stream(&self, stream: u64) -> u64 {
        stream ^ ((self.vehicle as u64) << 48)
    }

    /// Number of frames in the scenario.
    pub fn frame_count(&self) -> u64 {
        // Saturating float->int cast; validated duration and fps keep it small.
        (self.duration_s * self.camera.fps).floor() as u64
    }
}

/// Piecewise-linear lookup in a `[[t, value], ...]` profile, holding the end values.
pub fn profile_value(profile: &[[f64; 2]], default: f64, t: f64) -> f64 {
    let Some(first) = profile.first() else {
        return default;
    };
    if t <= first[0] {
        return first[1];
    }
    for w in profile.windows(2) {
        let ([t0, v0], [t1, v1]) = (w[0], w[1]);
        if t <= t1 {
            return v0 + (v1 - v0) * (t - t0) / (t1 - t0);
        }
    }
    profile.last().map_or(default, |l| l[1])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_field_is_named() {
        let text = SHIPPED[0].1.replace("[camera]", "[camera]\nfsp = 3");
        let err = Scenario::from_toml(&text, "x.toml")
            .unwrap_err()
            .to_string();
        assert!(err.contains("fsp"), "{err}");
        assert!(err.contains("x.toml"), "{err}");
    }

    #[test]
    fn invalid_toml_reports_line() {
        let err = Scenario::from_toml("name = \"a\"\nduration_s = = 3\n", "y.toml")
            .unwrap_err()
            .to_string();
        assert!(err.contains("line 2"), "{err}");
    }

    #[test]
    fn unknown_name_lists_shipped() {
        let err = Scenario::load("no_such_scenario").unwrap_err().to_string();
        assert!(err.contains("calm_baseline"), "{err}");
    }

    #[test]
    fn profile_interpolates_and_holds() {
        let p = [[0.0, 1.0], [10.0, 3.0]];
        assert_eq!(profile_value(&p, 9.0, -1.0), 1.0);
        assert_eq!(profile_value(&p, 9.0, 5.0), 2.0);
        assert_eq!(profile_value(&p, 9.0, 20.0), 3.0);
        assert_eq!(profile_value(&[], 9.0, 5.0), 9.0);
    }
}
