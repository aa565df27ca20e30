//! Scenario files: the TOML schema, loading with field-naming errors, validation and the
//! named scenarios shipped in `sim/scenarios/` (embedded in the binary).
//!
//! The schema is documented field by field in `sim/README.md`; every struct here denies
//! unknown fields so that a typo is an error that names the field rather than a silently
//! ignored setting.

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

/// The problems found so far by [`Scenario::validate`].
#[derive(Debug, Default)]
struct Problems(Vec<FieldProblem>);

impl Problems {
    /// Records a problem with `field` unless `ok`.
    fn require(&mut self, ok: bool, field: &str, problem: &str) {
        if !ok {
            self.0.push(FieldProblem {
                field: field.to_string(),
                problem: problem.to_string(),
            });
        }
    }
}

/// The scenarios shipped with the simulator: (name, TOML text).
pub const SHIPPED: &[(&str, &str)] = &[
    (
        "calm_baseline",
        include_str!("../scenarios/calm_baseline.toml"),
    ),
    ("fast_drone", include_str!("../scenarios/fast_drone.toml")),
    (
        "gimbal_swings",
        include_str!("../scenarios/gimbal_swings.toml"),
    ),
    (
        "leave_and_return",
        include_str!("../scenarios/leave_and_return.toml"),
    ),
    (
        "high_altitude_tiny",
        include_str!("../scenarios/high_altitude_tiny.toml"),
    ),
    (
        "swimmer_group",
        include_str!("../scenarios/swimmer_group.toml"),
    ),
    (
        "boats_crossing",
        include_str!("../scenarios/boats_crossing.toml"),
    ),
    (
        "camera_desync",
        include_str!("../scenarios/camera_desync.toml"),
    ),
    (
        "gimbal_pitch_bias",
        include_str!("../scenarios/gimbal_pitch_bias.toml"),
    ),
    (
        "telemetry_dropout",
        include_str!("../scenarios/telemetry_dropout.toml"),
    ),
    (
        "mixed_mission_soak",
        include_str!("../scenarios/mixed_mission_soak.toml"),
    ),
    (
        "ardupilot_servo",
        include_str!("../scenarios/ardupilot_servo.toml"),
    ),
    (
        "lawnmower_search",
        include_str!("../scenarios/lawnmower_search.toml"),
    ),
    (
        "expanding_square",
        include_str!("../scenarios/expanding_square.toml"),
    ),
    (
        "sector_search",
        include_str!("../scenarios/sector_search.toml"),
    ),
];

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

    /// Checks ranges and cross-references; the error names every offending field.
    pub fn validate(&self, origin: &str) -> Result<(), ScenarioError> {
        let mut p = Problems::default();
        self.check_flight(&mut p);
        check_drone(&self.drone, &mut p);
        check_path(&self.drone.path, &mut p);
        check_gimbal(&self.gimbal, &mut p);
        check_camera(&self.camera, &mut p);
        check_sea(&self.sea, &mut p);
        self.check_objects(&mut p);
        self.check_events(&mut p);
        check_faults(&self.faults, &mut p);
        check_telemetry(&self.telemetry, &mut p);
        check_detector(&self.detector, &mut p);
        if p.0.is_empty() {
            Ok(())
        } else {
            Err(ScenarioError::Invalid {
                origin: origin.to_string(),
                problems: p.0,
            })
        }
    }

    /// `duration_s` and `origin`.
    fn check_flight(&self, p: &mut Problems) {
        let o = &self.origin;
        p.require(
            finite(self.duration_s) && self.duration_s > 0.0 && self.duration_s <= 86_400.0,
            "duration_s",
            "must be in (0, 86400]",
        );
        p.require(
            finite(o.lat_deg) && o.lat_deg.abs() <= 89.0,
            "origin.lat_deg",
            "must be within [-89, 89]",
        );
        p.require(
            finite(o.lon_deg) && o.lon_deg.abs() <= 180.0,
            "origin.lon_deg",
            "must be within [-180, 180]",
        );
        p.require(
            finite(o.alt_amsl_m) && finite(o.start_unix_s),
            "origin",
            "values must be finite",
        );
    }

    /// `objects[i]`, and their total count.
    fn check_objects(&self, p: &mut Problems) {
        let total: u64 = self.objects.iter().map(|o| u64::from(o.count)).sum();
        p.require(
            total <= 10_000,
            "objects",
            "more than 10000 objects in total",
        );
        for (i, o) in self.objects.iter().enumerate() {
            let field = |name: &str| format!("objects[{i}].{name}");
            if let Some([lo, hi]) = o.speed_mps {
                p.require(
                    finite(lo) && finite(hi) && 0.0 <= lo && lo <= hi && hi <= 40.0,
                    &field("speed_mps"),
                    "must be [min, max] with 0 <= min <= max <= 40",
                );
            }
            p.require(
                finite(o.spawn_radius_m) && o.spawn_radius_m >= 0.0,
                &field("spawn_radius_m"),
                "must be >= 0",
            );
            p.require(
                finite(o.random_walk) && (0.0..=5.0).contains(&o.random_walk),
                &field("random_walk"),
                "must be within [0, 5]",
            );
            if let Some([l, w]) = o.size_m {
                p.require(
                    finite(l) && finite(w) && l > 0.05 && w > 0.05 && l < 100.0 && w < 100.0,
                    &field("size_m"),
                    "must be within (0.05, 100)",
                );
            }
        }
    }

    /// `events[i]`: each names an existing group and member, and fits its group's class.
    fn check_events(&self, p: &mut Problems) {
        for (i, e) in self.events.iter().enumerate() {
            let field = |name: &str| format!("events[{i}].{name}");
            let group = self.objects.get(e.group);
            match group {
                None => p.require(
                    false,
                    &field("group"),
                    &format!(
                        "no object group {} (there are {})",
                        e.group,
                        self.objects.len()
                    ),
                ),
                Some(g) => p.require(
                    e.member < g.count,
                    &field("member"),
                    &format!("group {} has only {} objects", e.group, g.count),
                ),
            }
            p.require(
                finite(e.at_s) && e.at_s >= 0.0,
                &field("at_s"),
                "must be >= 0",
            );
            match (e.kind, group) {
                (EventKind::RemoveLifejacket, Some(g)) => p.require(
                    g.class == ObjectClass::Swimmer,
                    &field("kind"),
                    "remove_lifejacket needs a swimmer group",
                ),
                (EventKind::ChangeClass, _) => {
                    p.require(e.to.is_some(), &field("to"), "change_class needs `to`")
                }
                (EventKind::Stop | EventKind::Resume, Some(g)) => p.require(
                    g.class != ObjectClass::Buoy,
                    &field("kind"),
                    "buoys are moored: they cannot stop or resume",
                ),
                (EventKind::RemoveLifejacket | EventKind::Stop | EventKind::Resume, None) => {}
            }
            if e.kind == EventKind::Resume {
                let stopped_before = self.events.iter().any(|s| {
                    s.kind == EventKind::Stop
                        && s.group == e.group
                        && s.member == e.member
                        && s.at_s < e.at_s
                });
                p.require(
                    stopped_before,
                    &field("kind"),
                    "resume needs an earlier stop of the same object",
                );
            }
        }
    }

    /// Number of frames in the scenario.
    pub fn frame_count(&self) -> u64 {
        // Saturating float->int cast; validated duration and fps keep it small.
        (self.duration_s * self.camera.fps).floor() as u64
    }
}

fn finite(v: f64) -> bool {
    v.is_finite()
}

/// `drone.*` but the path.
fn check_drone(d: &Drone, p: &mut Problems) {
    p.require(
        finite(d.speed_mps) && (0.0..=40.0).contains(&d.speed_mps),
        "drone.speed_mps",
        "must be within [0, 40]",
    );
    p.require(
        finite(d.altitude_m) && (1.0..=2000.0).contains(&d.altitude_m),
        "drone.altitude_m",
        "must be within [1, 2000]",
    );
    p.require(
        finite(d.max_yaw_rate_deg_s) && d.max_yaw_rate_deg_s > 0.0,
        "drone.max_yaw_rate_deg_s",
        "must be > 0",
    );
    for (field, profile, lo, hi) in [
        ("drone.speed_profile", &d.speed_profile, 0.0, 40.0),
        ("drone.altitude_profile", &d.altitude_profile, 1.0, 2000.0),
    ] {
        if let Err(problem) = check_profile(profile, lo, hi) {
            p.require(false, field, &problem);
        }
    }
}

/// `drone.path`, by kind.
fn check_path(path: &Path2d, p: &mut Problems) {
    let all_finite = |v: &[f64]| v.iter().all(|v| finite(*v));
    match path {
        Path2d::Hover {
            at_ne_m,
            heading_deg,
        } => p.require(
            all_finite(at_ne_m) && finite(*heading_deg),
            "drone.path",
            "values must be finite",
        ),
        Path2d::Waypoints { points_ne_m, .. } => {
            if points_ne_m.len() < 2 {
                p.require(false, "drone.path.points_ne_m", "needs at least two points");
            } else {
                p.require(
                    all_finite(points_ne_m.as_flattened()),
                    "drone.path.points_ne_m",
                    "values must be finite",
                );
            }
        }
        Path2d::Loiter {
            center_ne_m,
            radius_m,
            ..
        } => {
            p.require(
                finite(*radius_m) && *radius_m >= 1.0,
                "drone.path.radius_m",
                "must be >= 1",
            );
            p.require(
                all_finite(center_ne_m),
                "drone.path.center_ne_m",
                "values must be finite",
            );
        }
        Path2d::Lawnmower { .. } => check_lawnmower(path, p),
        Path2d::ExpandingSquare {
            datum_ne_m,
            first_heading_deg,
            spacing_m,
            legs,
            ..
        } => {
            p.require(
                finite(*spacing_m) && *spacing_m > 1.0,
                "drone.path.spacing_m",
                "must be > 1",
            );
            p.require(
                (1..=1000).contains(legs),
                "drone.path.legs",
                "must be within [1, 1000]",
            );
            p.require(
                all_finite(datum_ne_m) && finite(*first_heading_deg),
                "drone.path",
                "values must be finite",
            );
        }
        Path2d::Sector {
            datum_ne_m,
            radius_m,
            first_heading_deg,
            patterns,
            ..
        } => {
            p.require(
                finite(*radius_m) && *radius_m > 1.0,
                "drone.path.radius_m",
                "must be > 1",
            );
            p.require(
                (1..=6).contains(patterns),
                "drone.path.patterns",
                "must be within [1, 6]",
            );
            p.require(
                all_finite(datum_ne_m) && finite(*first_heading_deg),
                "drone.path",
                "values must be finite",
            );
        }
    }
}

/// `drone.path` of kind `lawnmower` (nothing for another kind).
fn check_lawnmower(path: &Path2d, p: &mut Problems) {
    let Path2d::Lawnmower {
        start_ne_m,
        heading_deg,
        leg_length_m,
        spacing_m,
        legs,
    } = path
    else {
        return;
    };
    p.require(
        finite(*leg_length_m) && *leg_length_m > 1.0,
        "drone.path.leg_length_m",
        "must be > 1",
    );
    p.require(
        finite(*spacing_m) && *spacing_m > 0.0,
        "drone.path.spacing_m",
        "must be > 0",
    );
    p.require(
        (1..=1000).contains(legs),
        "drone.path.legs",
        "must be within [1, 1000]",
    );
    p.require(
        start_ne_m.iter().all(|v| finite(*v)) && finite(*heading_deg),
        "drone.path",
        "values must be finite",
    );
}

/// `gimbal.*`; the sweep and swing fields only in their modes.
fn check_gimbal(g: &Gimbal, p: &mut Problems) {
    p.require(
        finite(g.pitch_deg) && (0.0..=90.0).contains(&g.pitch_deg),
        "gimbal.pitch_deg",
        "must be within [0, 90] (below the horizon)",
    );
    if g.mode == GimbalMode::Sweep {
        p.require(
            finite(g.sweep_period_s) && g.sweep_period_s > 0.1,
            "gimbal.sweep_period_s",
            "must be > 0.1",
        );
    }
    if g.mode == GimbalMode::Swings {
        p.require(
            finite(g.swing_interval_s) && g.swing_interval_s > 0.1,
            "gimbal.swing_interval_s",
            "must be > 0.1",
        );
        p.require(
            finite(g.swing_rate_deg_s) && g.swing_rate_deg_s > 0.0,
            "gimbal.swing_rate_deg_s",
            "must be > 0",
        );
    }
}

/// `camera.*`.
fn check_camera(c: &Camera, p: &mut Problems) {
    p.require(
        (16..=7680).contains(&c.width_px),
        "camera.width_px",
        "must be within [16, 7680]",
    );
    p.require(
        (16..=4320).contains(&c.height_px),
        "camera.height_px",
        "must be within [16, 4320]",
    );
    p.require(
        finite(c.hfov_deg) && c.hfov_deg > 1.0 && c.hfov_deg < 170.0,
        "camera.hfov_deg",
        "must be within (1, 170)",
    );
    p.require(
        finite(c.fps) && c.fps > 0.0 && c.fps <= 240.0,
        "camera.fps",
        "must be within (0, 240]",
    );
    p.require(
        finite(c.capture_latency_ms) && c.capture_latency_ms >= 0.0,
        "camera.capture_latency_ms",
        "must be >= 0",
    );
}

/// `sea.*`.
fn check_sea(s: &Sea, p: &mut Problems) {
    p.require(
        s.current_ne_mps.iter().all(|v| finite(*v))
            && s.current_ne_mps[0].hypot(s.current_ne_mps[1]) <= 5.0,
        "sea.current_ne_mps",
        "must be finite, at most 5 m/s",
    );
    p.require(
        s.wind_ne_mps.iter().all(|v| finite(*v))
            && s.wind_ne_mps[0].hypot(s.wind_ne_mps[1]) <= 40.0,
        "sea.wind_ne_mps",
        "must be finite, at most 40 m/s",
    );
    p.require(
        finite(s.wave_length_m) && s.wave_length_m > 0.1,
        "sea.wave_length_m",
        "must be > 0.1",
    );
    p.require(
        finite(s.wave_height_m) && s.wave_height_m >= 0.0,
        "sea.wave_height_m",
        "must be >= 0",
    );
    p.require(
        finite(s.sun_elevation_deg) && (0.0..=90.0).contains(&s.sun_elevation_deg),
        "sea.sun_elevation_deg",
        "must be within [0, 90]",
    );
    p.require(
        finite(s.glint) && (0.0..=1.0).contains(&s.glint),
        "sea.glint",
        "must be within [0, 1]",
    );
}

/// `faults.*`.
fn check_faults(f: &Faults, p: &mut Problems) {
    for (j, w) in f.dropouts.iter().enumerate() {
        p.require(
            finite(w[0]) && finite(w[1]) && w[0] >= 0.0 && w[1] > 0.0,
            &format!("faults.dropouts[{j}]"),
            "must be [start_s >= 0, duration_s > 0]",
        );
    }
    for (field, v) in [
        ("faults.telemetry_latency_ms", f.telemetry_latency_ms),
        ("faults.attitude_noise_deg", f.attitude_noise_deg),
        ("faults.gimbal_noise_deg", f.gimbal_noise_deg),
        ("faults.gps_noise_m", f.gps_noise_m),
    ] {
        p.require(finite(v) && v >= 0.0, field, "must be >= 0");
    }
    for (j, r) in f.reboots_s.iter().enumerate() {
        p.require(
            finite(*r) && *r >= 0.0,
            &format!("faults.reboots_s[{j}]"),
            "must be a time >= 0",
        );
    }
}

/// `telemetry.*`.
fn check_telemetry(t: &Telemetry, p: &mut Problems) {
    p.require(
        finite(t.rate_jitter) && (0.0..0.5).contains(&t.rate_jitter),
        "telemetry.rate_jitter",
        "must be within [0, 0.5)",
    );
    p.require(
        finite(t.boot_time_s) && t.boot_time_s >= 0.0,
        "telemetry.boot_time_s",
        "must be >= 0",
    );
}

/// `detector.*`.
fn check_detector(det: &Detector, p: &mut Problems) {
    p.require(
        finite(det.miss_floor) && (0.0..=1.0).contains(&det.miss_floor),
        "detector.miss_floor",
        "must be within [0, 1]",
    );
    p.require(
        finite(det.false_positives_per_frame) && det.false_positives_per_frame >= 0.0,
        "detector.false_positives_per_frame",
        "must be >= 0",
    );
}

fn check_profile(profile: &[[f64; 2]], lo: f64, hi: f64) -> Result<(), String> {
    let mut last_t = f64::NEG_INFINITY;
    for (i, [t, v]) in profile.iter().enumerate() {
        if !t.is_finite() || !v.is_finite() {
            return Err(format!("entry {i}: values must be finite"));
        }
        if *t <= last_t {
            return Err(format!("entry {i}: times must increase"));
        }
        if *v < lo || *v > hi {
            return Err(format!("entry {i}: value {v} outside [{lo}, {hi}]"));
        }
        last_t = *t;
    }
    Ok(())
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
    fn every_shipped_scenario_loads() {
        for (name, _) in SHIPPED {
            let s = Scenario::load(name).unwrap();
            assert_eq!(&s.name, name);
        }
    }

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
    fn out_of_range_field_is_named() {
        let text = SHIPPED[0].1.replace("fps = 30", "fps = -2");
        let err = Scenario::from_toml(&text, "x.toml")
            .unwrap_err()
            .to_string();
        assert!(err.contains("camera.fps"), "{err}");
    }

    /// Three mistakes in three parts of the file: all three are reported, each with its field
    /// and its own message, in schema order.
    #[test]
    fn every_invalid_field_is_reported() {
        let text = SHIPPED[0]
            .1
            .replace("fps = 30", "fps = -2")
            .replace("glint = 0.4", "glint = 2")
            + "\n[telemetry]\nboot_time_s = -1\n";
        let err = Scenario::from_toml(&text, "x.toml").unwrap_err();
        let ScenarioError::Invalid { origin, problems } = &err else {
            panic!("{err}")
        };
        assert_eq!(origin, "x.toml");
        let fields: Vec<&str> = problems.iter().map(|p| p.field.as_str()).collect();
        assert_eq!(fields, ["camera.fps", "sea.glint", "telemetry.boot_time_s"]);
        assert_eq!(
            err.to_string(),
            "invalid scenario x.toml: field `camera.fps`: must be within (0, 240]; \
             field `sea.glint`: must be within [0, 1]; \
             field `telemetry.boot_time_s`: must be >= 0"
        );
    }

    #[test]
    fn an_event_of_a_missing_group_is_reported_with_the_rest() {
        let mut s = Scenario::load("calm_baseline").unwrap();
        s.duration_s = 0.0;
        s.events.push(Event {
            at_s: -1.0,
            group: 99,
            member: 0,
            kind: EventKind::ChangeClass,
            to: None,
        });
        let Err(ScenarioError::Invalid { problems, .. }) = s.validate("t") else {
            panic!("validated")
        };
        let n = s.events.len() - 1;
        let fields: Vec<String> = problems.into_iter().map(|p| p.field).collect();
        assert_eq!(
            fields,
            [
                "duration_s".to_string(),
                format!("events[{n}].group"),
                format!("events[{n}].at_s"),
                format!("events[{n}].to")
            ]
        );
    }

    fn event(kind: EventKind, group: usize, member: u32, at_s: f64) -> Event {
        Event {
            kind,
            group,
            member,
            at_s,
            to: None,
        }
    }

    /// `stop` and `resume` are checked like the other events (group, member), plus their own
    /// rules: not on a buoy, and a resume only after a stop of the same object.
    #[test]
    fn stop_and_resume_are_validated() {
        let mut s = Scenario::load("lawnmower_search").unwrap();
        let buoy = s
            .objects
            .iter()
            .position(|g| g.class == ObjectClass::Buoy)
            .unwrap();
        let swimmers = s
            .objects
            .iter()
            .position(|g| g.class == ObjectClass::Swimmer)
            .unwrap();
        let n = s.events.len();
        s.events.extend([
            event(EventKind::Stop, buoy, 0, 10.0),
            event(EventKind::Stop, swimmers, 9999, 10.0),
            event(EventKind::Resume, swimmers, 1, 10.0),
            event(EventKind::Stop, swimmers, 2, 20.0),
            event(EventKind::Resume, swimmers, 2, 19.0),
            event(EventKind::Stop, 99, 0, 10.0),
        ]);
        let Err(ScenarioError::Invalid { problems, .. }) = s.validate("t") else {
            panic!("validated")
        };
        let fields: Vec<String> = problems.into_iter().map(|p| p.field).collect();
        assert_eq!(
            fields,
            [
                format!("events[{n}].kind"),
                format!("events[{}].member", n + 1),
                format!("events[{}].kind", n + 2),
                format!("events[{}].kind", n + 4),
                format!("events[{}].group", n + 5),
            ]
        );
        // A stop and a later resume of a swimmer are fine.
        s.events.truncate(n);
        s.events.push(event(EventKind::Stop, swimmers, 2, 20.0));
        s.events.push(event(EventKind::Resume, swimmers, 2, 40.0));
        s.validate("t").unwrap();
    }

    #[test]
    fn wind_defaults_to_calm_and_is_range_checked() {
        let s = Scenario::load("mixed_mission_soak").unwrap();
        assert_eq!(s.sea.wind_ne_mps, [0.0, 0.0]);
        let text = SHIPPED[0]
            .1
            .replace("[sea]", "[sea]\nwind_ne_mps = [50.0, 0.0]");
        let err = Scenario::from_toml(&text, "x.toml")
            .unwrap_err()
            .to_string();
        assert!(err.contains("sea.wind_ne_mps"), "{err}");
    }

    #[test]
    fn new_path_kinds_are_range_checked() {
        let base = SHIPPED[0].1;
        let start = base.find("[drone.path]").unwrap();
        let end = start + base[start..].find("\n\n").unwrap();
        for (path, field) in [
            (
                "kind = \"expanding_square\"\ndatum_ne_m = [0.0, 0.0]\nfirst_heading_deg = 0.0\nspacing_m = 0.5\nlegs = 4",
                "drone.path.spacing_m",
            ),
            (
                "kind = \"sector\"\ndatum_ne_m = [0.0, 0.0]\nfirst_heading_deg = 0.0\nradius_m = 100.0\npatterns = 0",
                "drone.path.patterns",
            ),
        ] {
            let text = format!("{}[drone.path]\n{path}{}", &base[..start], &base[end..]);
            let err = Scenario::from_toml(&text, "x.toml")
                .unwrap_err()
                .to_string();
            assert!(err.contains(field), "{err}");
        }
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
