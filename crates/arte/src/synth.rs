//! Synthetic tyre-road audio per road, with rain and passing-car noise.
//!
//! No public tyre-road recordings are reachable from this project, so ARTE is
//! trained and tested on sound synthesised from a physically motivated,
//! documented model (crate README, "Synthetic audio", with its sources). In
//! short, the signal at a microphone near the tyre is the sum of
//!
//! 1. the tyre/road rolling-noise "hump": broadband noise shaped by two
//!    band-pass sections around f_h ≈ 0.75–1.25 kHz (tyre dependent, rising
//!    slowly with speed), level L = B·log10(v/v_ref) with B = 30–40 dB/decade
//!    (Sandberg & Ejsmont 2002; CPX, ISO 11819-2);
//! 2. texture-driven tyre vibration noise, a band around f_t = v/λ_t
//!    (macrotexture wavelength λ_t), strong on coarse surfaces;
//! 3. road-specific events: sett-joint impacts at ≈ v/L_sett on stone,
//!    Poisson particle crunch and stone-throw pings on gravel, compaction
//!    crunch and squeak on snow;
//! 4. road-specific filtering: snow damps high frequencies (porous absorption);
//!    wet roads add water-film spray/splash hiss above ≈ 1.5–3.5 kHz whose
//!    level grows with film depth and faster than rolling noise with speed;
//! 5. the vehicle and microphone: wind rumble (∝ v³), microphone high-pass,
//!    spectral tilt, self-noise and gain.
//!
//! Every parameter varies per recording (drawn from the seed), so classes
//! overlap the way real surfaces do (coarse asphalt vs gravel, thin water
//! films vs dry, slushy snow vs wet). Rain (broadband hiss + droplet
//! impulses) and passing cars (engine harmonics + tyre hump, Doppler shifted,
//! with a pass-by envelope) are mixed in at a chosen SNR.
//!
//! [`RoadAudioSynth`] is a streaming generator: `fill` continues seamlessly
//! across calls, speed changes and road changes, and allocates nothing after
//! construction. [`render`] produces a whole recording with the noise scaled
//! to the exact SNR over the recording.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// The road classes, in class-index order; names match `config/roads.toml`.
pub const ROADS: [&str; 6] = [
    "asphalt",
    "gravel",
    "snow",
    "stone",
    "wet_asphalt",
    "wet_stone",
];

/// Class index of a road name (exact, lower case), or `None`.
pub fn road_index(name: &str) -> Option<usize> {
    ROADS.iter().position(|r| *r == name)
}

mod aliases;
pub use aliases::{AliasError, AliasValue, AudioAcqAliases, ResolvedAliases, SynthAliases};

/// Reference speed of the level laws: 30 km/h.
pub const V_REF_MPS: f64 = 30.0 / 3.6;
/// Speed of sound (m/s) for the Doppler shift of passing cars.
const C_SOUND: f64 = 343.0;
/// Nominal RMS of the asphalt rolling noise at v_ref before microphone gain.
const HUMP_RMS: f64 = 0.05;

/// Noise mixed into the road sound.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoiseConfig {
    /// Rain: broadband hiss and droplet impulses.
    pub rain: bool,
    /// Passing cars: engine harmonics and tyre noise with Doppler and pass-by envelope.
    pub car: bool,
    /// Signal-to-noise ratio (dB): road-sound power over total noise power.
    pub snr_db: f64,
}

/// Configuration of the synthesiser.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SynthConfig {
    /// Output sample rate (Hz).
    pub sample_rate: u32,
    /// Noise to mix in; `None` for clean road sound.
    pub noise: Option<NoiseConfig>,
}

impl Default for SynthConfig {
    fn default() -> Self {
        Self {
            sample_rate: 44_100,
            noise: None,
        }
    }
}

/// Errors of the synthesiser.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SynthError {
    /// A config field is out of range.
    #[error("synth config: field `{field}`: {reason}")]
    InvalidConfig {
        /// The field.
        field: &'static str,
        /// Why.
        reason: String,
    },
    /// A segment of a recording is invalid.
    #[error("synth segment {index}: {reason}")]
    InvalidSegment {
        /// Segment index.
        index: usize,
        /// Why.
        reason: String,
    },
}

/// The limits of a noise level `snr_db`, dB: the one range the synthesiser,
/// audio-acq's `[synth.noise]` and the `--snr-db` of `grip` accept.
pub const SNR_LIMITS_DB: std::ops::RangeInclusive<f64> = -30.0..=80.0;

impl SynthConfig {
    /// Checks ranges (NaN fails).
    pub fn validate(&self) -> Result<(), SynthError> {
        if !(8_000..=192_000).contains(&self.sample_rate) {
            return Err(SynthError::InvalidConfig {
                field: "sample_rate",
                reason: format!("{} Hz is outside 8000..=192000", self.sample_rate),
            });
        }
        if let Some(n) = &self.noise
            && !SNR_LIMITS_DB.contains(&n.snr_db)
        {
            return Err(SynthError::InvalidConfig {
                field: "noise.snr_db",
                reason: format!(
                    "{} dB is outside {}..={}",
                    n.snr_db,
                    SNR_LIMITS_DB.start(),
                    SNR_LIMITS_DB.end()
                ),
            });
        }
        Ok(())
    }
}

fn db(x: f64) -> f64 {
    10f64.powf(x / 20.0)
}

fn uni(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * rng.random::<f64>()
}

fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    rng.sample(StandardNormal)
}

// ---------------------------------------------------------------- filters

/// Biquad, transposed direct form II (RBJ Audio EQ Cookbook coefficients).
#[derive(Clone, Copy, Debug, Default)]
struct Biquad {
    b0: f64,
    b1: f64,
    b2: f64,
    a1: f64,
    a2: f64,
    z1: f64,
    z2: f64,
}

impl Biquad {
    fn set(&mut self, b: [f64; 3], a: [f64; 3]) {
        self.b0 = b[0] / a[0];
        self.b1 = b[1] / a[0];
        self.b2 = b[2] / a[0];
        self.a1 = a[1] / a[0];
        self.a2 = a[2] / a[0];
    }
    fn w(fs: f64, f: f64, q: f64) -> (f64, f64) {
        let w0 = 2.0 * PI * f.clamp(1.0, 0.49 * fs) / fs;
        (w0.cos(), w0.sin() / (2.0 * q))
    }
    /// Band-pass, 0 dB peak gain.
    fn set_bandpass(&mut self, fs: f64, f: f64, q: f64) {
        let (c, al) = Self::w(fs, f, q);
        self.set([al, 0.0, -al], [1.0 + al, -2.0 * c, 1.0 - al]);
    }
    fn set_highpass(&mut self, fs: f64, f: f64, q: f64) {
        let (c, al) = Self::w(fs, f, q);
        self.set(
            [(1.0 + c) / 2.0, -(1.0 + c), (1.0 + c) / 2.0],
            [1.0 + al, -2.0 * c, 1.0 - al],
        );
    }
    /// Two-pole resonator with unit impulse-response peak scale: poles at
    /// r e^{±jθ}, r = e^{−1/(τ fs)}; excited by impulses it rings at `f` and
    /// decays with time constant `tau`.
    fn set_resonator(&mut self, fs: f64, f: f64, tau: f64) {
        let r = (-1.0 / (tau * fs)).exp();
        let th = 2.0 * PI * f.clamp(1.0, 0.49 * fs) / fs;
        self.set([th.sin(), 0.0, 0.0], [1.0, -2.0 * r * th.cos(), r * r]);
    }
    #[inline]
    fn tick(&mut self, x: f64) -> f64 {
        let y = self.b0 * x + self.z1;
        self.z1 = self.b1 * x - self.a1 * y + self.z2;
        self.z2 = self.b2 * x - self.a2 * y;
        y
    }
    /// Output power for unit-variance white input: Σ h[n]² (numerically, on
    /// a copy with zero state).
    fn white_gain2(&self, n: usize) -> f64 {
        let mut c = *self;
        c.z1 = 0.0;
        c.z2 = 0.0;
        let mut e = 0.0;
        for i in 0..n {
            let h = c.tick(if i == 0 { 1.0 } else { 0.0 });
            e += h * h;
        }
        e
    }
}

/// One-pole low-pass y += a (x − y).
#[derive(Clone, Copy, Debug, Default)]
struct OnePole {
    a: f64,
    y: f64,
}

impl OnePole {
    fn lowpass(fs: f64, f: f64) -> Self {
        Self {
            a: 1.0 - (-2.0 * PI * f / fs).exp(),
            y: 0.0,
        }
    }
    fn set(&mut self, fs: f64, f: f64) {
        self.a = 1.0 - (-2.0 * PI * f / fs).exp();
    }
    #[inline]
    fn tick(&mut self, x: f64) -> f64 {
        self.y += self.a * (x - self.y);
        self.y
    }
}

/// A gain that glides to its target with a short time constant, so road
/// changes are abrupt to the ear (≈ 3 ms) but click-free.
#[derive(Clone, Copy, Debug, Default)]
struct Glide {
    v: f64,
    target: f64,
}

impl Glide {
    #[inline]
    fn tick(&mut self, a: f64) -> f64 {
        self.v += a * (self.target - self.v);
        self.v
    }
}

// ---------------------------------------------------------------- per-recording variation

/// The per-road surface parameters drawn for one recording.
#[derive(Clone, Debug, Serialize)]
pub struct SurfaceParams {
    /// Rolling-noise level offset relative to dense dry asphalt (dB).
    pub hump_db: f64,
    /// Factor on the tyre's hump frequency (snow < 1).
    pub hump_freq_factor: f64,
    /// Texture-noise level relative to the hump (dB).
    pub texture_db: f64,
    /// Macrotexture wavelength λ_t (m): texture band centre v/λ_t.
    pub texture_wavelength_m: f64,
    /// Stone: sett length (m), joint impacts at v / sett_length.
    pub sett_length_m: f64,
    /// Stone: relative jitter of the joint spacing.
    pub sett_jitter: f64,
    /// Stone: impact level relative to the hump (dB); −∞ (none) elsewhere.
    pub impact_db: f64,
    /// Stone: carcass thump frequency (Hz) and decay (s).
    pub thump_hz: f64,
    /// Decay time constant of the thump (s).
    pub thump_tau_s: f64,
    /// Stone: tread snap click band centre (Hz).
    pub click_hz: f64,
    /// Crunch (gravel particles, snow compaction): events per metre.
    pub crunch_per_m: f64,
    /// Crunch band centre (Hz).
    pub crunch_hz: f64,
    /// Crunch level relative to the hump (dB); −∞ for none.
    pub crunch_db: f64,
    /// Gravel: stone-throw pings per metre.
    pub ping_per_m: f64,
    /// Ping resonance (Hz) and decay (s).
    pub ping_hz: f64,
    /// Ping decay time constant (s).
    pub ping_tau_s: f64,
    /// Ping level relative to the hump (dB); −∞ for none.
    pub ping_db: f64,
    /// Snow squeak tone (Hz) and level (dB rel. hump); −∞ for none.
    pub squeak_hz: f64,
    /// Squeak level (dB rel. hump).
    pub squeak_db: f64,
    /// High-frequency damping corner (Hz) of the surface (snow), or `None`.
    pub damping_hz: Option<f64>,
    /// Water film: spray hiss high-pass corner (Hz).
    pub spray_hz: f64,
    /// Spray level relative to the hump at v_ref (dB); −∞ for dry.
    pub spray_db: f64,
    /// Depth of the slow splash amplitude modulation (0..1).
    pub splash_mod: f64,
}

/// Everything drawn per recording: the tyre, the microphone, and one
/// [`SurfaceParams`] per road (so a recording with road changes keeps its car).
#[derive(Clone, Debug, Serialize)]
pub struct Variation {
    /// Tyre rolling-noise hump centre at v_ref (Hz).
    pub hump_hz: f64,
    /// Q of each of the two hump band-pass sections.
    pub hump_q: f64,
    /// Speed law slope B: L = B log10(v/v_ref) (dB per decade).
    pub speed_slope_db: f64,
    /// Hump frequency speed exponent κ: f_h ∝ (v/v_ref)^κ.
    pub hump_speed_exp: f64,
    /// Microphone gain (dB).
    pub mic_gain_db: f64,
    /// Microphone high-shelf tilt above ≈ 2 kHz (linear factor − 1).
    pub mic_tilt: f64,
    /// Microphone / mount high-pass corner (Hz).
    pub mic_highpass_hz: f64,
    /// Wind rumble level relative to the hump at v_ref (dB).
    pub wind_db: f64,
    /// Per road, in [`ROADS`] order.
    pub surfaces: Vec<SurfaceParams>,
}

fn draw_variation(rng: &mut ChaCha8Rng) -> Variation {
    let none = f64::NEG_INFINITY;
    let base = |rng: &mut ChaCha8Rng| SurfaceParams {
        hump_db: 0.0,
        hump_freq_factor: 1.0,
        texture_db: -16.0,
        texture_wavelength_m: uni(rng, 0.008, 0.03),
        sett_length_m: 0.12,
        sett_jitter: 0.05,
        impact_db: none,
        thump_hz: 150.0,
        thump_tau_s: 0.008,
        click_hz: 2500.0,
        crunch_per_m: 0.0,
        crunch_hz: 3000.0,
        crunch_db: none,
        ping_per_m: 0.0,
        ping_hz: 2500.0,
        ping_tau_s: 0.01,
        ping_db: none,
        squeak_hz: 2000.0,
        squeak_db: none,
        damping_hz: None,
        spray_hz: 2500.0,
        spray_db: none,
        splash_mod: 0.0,
    };
    // Dense to coarse (chip-seal) asphalt: coarseness raises texture noise
    // and the hump, the overlap with gravel.
    let asphalt = |rng: &mut ChaCha8Rng| {
        let c = rng.random::<f64>();
        let mut s = base(rng);
        s.hump_db = 2.5 * c + uni(rng, -1.0, 1.0);
        s.texture_db = -22.0 + 8.0 * c + uni(rng, -2.0, 2.0);
        s.texture_wavelength_m = uni(rng, 0.006, 0.012 + 0.02 * c);
        s
    };
    // Water film depth 0.2–2 mm (log-uniform): spray level −2..+10 dB re hump.
    let wet = |rng: &mut ChaCha8Rng, s: &mut SurfaceParams| {
        let depth_mm = 0.2 * 10f64.powf(rng.random::<f64>());
        s.spray_db = 0.0 + 8.0 * (depth_mm / 0.2).log10() + uni(rng, -2.0, 2.0);
        s.spray_hz = uni(rng, 1500.0, 3500.0);
        s.splash_mod = uni(rng, 0.2, 0.6);
    };
    let stone = |rng: &mut ChaCha8Rng| {
        let mut s = base(rng);
        s.hump_db = uni(rng, 1.0, 5.0);
        s.texture_db = uni(rng, -9.0, -2.0);
        s.sett_length_m = uni(rng, 0.08, 0.16);
        s.texture_wavelength_m = s.sett_length_m / uni(rng, 2.0, 5.0);
        s.sett_jitter = uni(rng, 0.03, 0.15);
        s.impact_db = uni(rng, 2.0, 8.0);
        s.thump_hz = uni(rng, 80.0, 250.0);
        s.thump_tau_s = uni(rng, 0.004, 0.012);
        s.click_hz = uni(rng, 1500.0, 4000.0);
        s
    };
    let gravel = |rng: &mut ChaCha8Rng| {
        let mut s = base(rng);
        s.hump_db = uni(rng, 0.0, 3.0);
        s.texture_db = uni(rng, -12.0, -3.0);
        s.texture_wavelength_m = uni(rng, 0.01, 0.03);
        s.crunch_per_m = uni(rng, 60.0, 250.0);
        s.crunch_hz = uni(rng, 2000.0, 5000.0);
        s.crunch_db = uni(rng, 0.0, 8.0);
        s.ping_per_m = uni(rng, 0.3, 1.5);
        s.ping_hz = uni(rng, 1500.0, 4000.0);
        s.ping_tau_s = uni(rng, 0.005, 0.02);
        s.ping_db = s.crunch_db + uni(rng, 0.0, 6.0);
        s
    };
    let snow = |rng: &mut ChaCha8Rng| {
        let mut s = base(rng);
        // 0: packed (often squeaks), 1: fresh (most damped), 2: slushy (some splash).
        let kind = rng.random_range(0..3u32);
        s.hump_db = uni(rng, -8.0, -3.0);
        s.hump_freq_factor = uni(rng, 0.65, 0.9);
        s.texture_db = uni(rng, -16.0, -8.0);
        s.texture_wavelength_m = uni(rng, 0.02, 0.06);
        s.crunch_per_m = uni(rng, 15.0, 60.0);
        s.crunch_hz = uni(rng, 400.0, 1500.0);
        s.crunch_db = uni(rng, -10.0, 0.0);
        s.damping_hz = Some(match kind {
            1 => uni(rng, 700.0, 1500.0),
            _ => uni(rng, 1000.0, 2500.0),
        });
        if kind == 0 && rng.random::<f64>() < 0.7 {
            s.squeak_hz = uni(rng, 1200.0, 3000.0);
            s.squeak_db = uni(rng, -14.0, -4.0);
        }
        if kind == 2 {
            s.spray_db = uni(rng, -22.0, -12.0);
            s.spray_hz = uni(rng, 1500.0, 3000.0);
            s.splash_mod = uni(rng, 0.2, 0.5);
        }
        s
    };
    let hump_hz = uni(rng, 750.0, 1250.0);
    let hump_q = uni(rng, 0.6, 1.0);
    let speed_slope_db = uni(rng, 30.0, 40.0);
    let hump_speed_exp = uni(rng, 0.1, 0.3);
    let mic_gain_db = uni(rng, -10.0, 6.0);
    let mic_tilt = uni(rng, -0.3, 0.4);
    let mic_highpass_hz = uni(rng, 30.0, 120.0);
    let wind_db = uni(rng, -30.0, -12.0);
    let s_asphalt = asphalt(rng);
    let s_gravel = gravel(rng);
    let s_snow = snow(rng);
    let s_stone = stone(rng);
    let mut s_wet_asphalt = asphalt(rng);
    wet(rng, &mut s_wet_asphalt);
    let mut s_wet_stone = stone(rng);
    wet(rng, &mut s_wet_stone);
    // Water fills the joints a little: softer snaps.
    s_wet_stone.impact_db -= uni(rng, 0.0, 3.0);
    s_wet_stone.click_hz *= 0.8;
    Variation {
        hump_hz,
        hump_q,
        speed_slope_db,
        hump_speed_exp,
        mic_gain_db,
        mic_tilt,
        mic_highpass_hz,
        wind_db,
        surfaces: vec![
            s_asphalt,
            s_gravel,
            s_snow,
            s_stone,
            s_wet_asphalt,
            s_wet_stone,
        ],
    }
}

// ---------------------------------------------------------------- noise sources

/// Rain: broadband hiss (band-limited) plus droplet impulses exciting short
/// resonances at random frequencies (round robin over 4 resonators).
struct Rain {
    hiss_lp: OnePole,
    hiss_hp: Biquad,
    hiss_gain: f64,
    drop_rate: f64,
    drops: [Biquad; 4],
    drop_norm: f64,
    next_drop: usize,
}

impl Rain {
    fn new(fs: f64, rng: &mut ChaCha8Rng) -> Self {
        let mut hiss_hp = Biquad::default();
        hiss_hp.set_highpass(fs, uni(rng, 150.0, 400.0), 0.707);
        let hiss_lp = OnePole::lowpass(fs, uni(rng, 3000.0, 8000.0));
        let mut probe = Biquad::default();
        probe.set_resonator(fs, 4000.0, 0.0015);
        Self {
            hiss_lp,
            hiss_hp,
            hiss_gain: db(uni(rng, -3.0, 3.0)),
            drop_rate: uni(rng, 200.0, 2000.0),
            drops: [Biquad::default(); 4],
            drop_norm: 1.0 / probe.white_gain2(2000).sqrt(),
            next_drop: 0,
        }
    }
    #[inline]
    fn tick(&mut self, fs: f64, rng: &mut ChaCha8Rng) -> f64 {
        let w = gauss(rng);
        let hiss = self.hiss_hp.tick(self.hiss_lp.tick(w)) * self.hiss_gain;
        let mut x = 0.0;
        if rng.random::<f64>() < self.drop_rate / fs {
            let d = &mut self.drops[self.next_drop];
            d.set_resonator(fs, uni(rng, 1000.0, 12_000.0), uni(rng, 0.0005, 0.003));
            // Lognormal drop sizes; mean energy per drop ≈ fixed so that the
            // droplet part carries about half the rain power.
            let a = (0.8 * gauss(rng) - 0.64).exp() * self.drop_norm * (fs / self.drop_rate).sqrt();
            x = a;
            self.next_drop = (self.next_drop + 1) % self.drops.len();
        }
        let mut drops = 0.0;
        for (i, d) in self.drops.iter_mut().enumerate() {
            drops += d.tick(if i == (self.next_drop + 3) % 4 {
                x
            } else {
                0.0
            });
        }
        hiss + drops
    }
}

/// Passing cars: one at a time, every 3–9 s, closest approach at lateral
/// distance d, constant speed u; amplitude ∝ d/r (spherical spreading),
/// frequencies scaled by the Doppler factor c/(c + dr/dt).
struct Car {
    t: f64,
    t0: f64,
    d: f64,
    u: f64,
    f_fire: f64,
    phases: [f64; 8],
    harm_amp: [f64; 8],
    tyre_bp: [Biquad; 2],
    tyre_norm: f64,
    tyre_level: f64,
    engine_level: f64,
    tyre_f: f64,
    update: u32,
}

impl Car {
    fn new(fs: f64, rng: &mut ChaCha8Rng) -> Self {
        let mut c = Self {
            t: 0.0,
            t0: 0.0,
            d: 3.0,
            u: 10.0,
            f_fire: 40.0,
            phases: [0.0; 8],
            harm_amp: [0.0; 8],
            tyre_bp: [Biquad::default(); 2],
            tyre_norm: 1.0,
            tyre_level: 1.0,
            engine_level: 1.0,
            tyre_f: 900.0,
            update: 0,
        };
        c.t0 = uni(rng, 0.5, 4.0);
        c.new_car(fs, rng);
        c
    }
    fn new_car(&mut self, fs: f64, rng: &mut ChaCha8Rng) {
        self.d = uni(rng, 2.5, 6.0);
        self.u = uni(rng, 8.0, 25.0);
        self.f_fire = uni(rng, 25.0, 80.0);
        for k in 0..8 {
            self.phases[k] = uni(rng, 0.0, 2.0 * PI);
            self.harm_amp[k] = uni(rng, 0.4, 1.2) / (k + 1) as f64;
        }
        self.tyre_f = uni(rng, 700.0, 1200.0);
        for b in &mut self.tyre_bp {
            b.set_bandpass(fs, self.tyre_f, 0.8);
        }
        let mut probe = self.tyre_bp[0];
        probe.z1 = 0.0;
        let g1 = probe.white_gain2(4000);
        self.tyre_norm = 1.0 / (g1 * 0.7).sqrt();
        let mix = uni(rng, -6.0, 6.0);
        self.engine_level = db(mix);
        self.tyre_level = db(-mix);
    }
    #[inline]
    fn tick(&mut self, fs: f64, rng: &mut ChaCha8Rng) -> f64 {
        let dt = 1.0 / fs;
        self.t += dt;
        let x = self.u * (self.t - self.t0);
        if x > 120.0 {
            // Gone: the next car arrives 3–9 s after this one passed.
            self.t0 = self.t + uni(rng, 3.0, 9.0) - 120.0 / self.u;
            self.new_car(fs, rng);
        }
        let x = self.u * (self.t - self.t0);
        let r = (x * x + self.d * self.d).sqrt();
        let rdot = self.u * x / r;
        let doppler = C_SOUND / (C_SOUND + rdot);
        let env = self.d / r;
        self.update += 1;
        if self.update >= 32 {
            self.update = 0;
            for b in &mut self.tyre_bp {
                let (z1, z2) = (b.z1, b.z2);
                b.set_bandpass(fs, self.tyre_f * doppler, 0.8);
                b.z1 = z1;
                b.z2 = z2;
            }
        }
        let mut eng = 0.0;
        for k in 0..8 {
            self.phases[k] += 2.0 * PI * self.f_fire * (k + 1) as f64 * doppler * dt;
            if self.phases[k] > 2.0 * PI {
                self.phases[k] -= 2.0 * PI;
            }
            eng += self.harm_amp[k] * self.phases[k].sin();
        }
        let w = gauss(rng);
        let t0 = self.tyre_bp[0].tick(w);
        let tyre = self.tyre_bp[1].tick(t0) * self.tyre_norm;
        env * (self.engine_level * eng + self.tyre_level * tyre)
    }
}

// ---------------------------------------------------------------- the synthesiser

/// Streaming tyre-road audio generator (see the module docs).
pub struct RoadAudioSynth {
    fs: f64,
    rng: ChaCha8Rng,
    noise_rng: ChaCha8Rng,
    var: Variation,
    road: Option<usize>,
    speed: f64,
    speed_target: f64,
    glide_a: f64,
    // rolling noise
    hump: [Biquad; 2],
    hump_norm: f64,
    g_hump: Glide,
    // texture
    texture: Biquad,
    texture_norm: f64,
    g_texture: Glide,
    // stone
    joint_countdown: f64,
    thump: Biquad,
    thump_norm: f64,
    click_bp: Biquad,
    click_env: f64,
    click_decay: f64,
    click_norm: f64,
    g_impact: Glide,
    // crunch (gravel, snow)
    crunch: Biquad,
    crunch_norm: f64,
    g_crunch: Glide,
    ping: Biquad,
    ping_norm: f64,
    g_ping: Glide,
    // squeak
    squeak_phase: f64,
    squeak_fm: OnePole,
    squeak_env: f64,
    squeak_on: bool,
    g_squeak: Glide,
    // surface damping (snow)
    damping: OnePole,
    g_damp: Glide,
    // spray
    spray_hp: Biquad,
    spray_lp: OnePole,
    spray_norm: f64,
    splash: OnePole,
    g_spray: Glide,
    g_splash: Glide,
    // vehicle + microphone
    wind: OnePole,
    wind_norm: f64,
    g_wind: Glide,
    mic_hp: Biquad,
    tilt_lp: OnePole,
    mic_gain: f64,
    self_noise: f64,
    // noise
    noise_cfg: Option<NoiseConfig>,
    rain: Option<Rain>,
    car: Option<Car>,
    noise_nominal_power: f64,
    road_power_ema: f64,
    ema_a: f64,
}

impl std::fmt::Debug for RoadAudioSynth {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RoadAudioSynth")
            .field("fs", &self.fs)
            .field("road", &self.road)
            .finish_non_exhaustive()
    }
}

impl RoadAudioSynth {
    /// Draws the per-recording variation from `seed` and builds every
    /// filter. Deterministic: the same config and seed give the same audio.
    pub fn new(cfg: &SynthConfig, seed: u64) -> Result<Self, SynthError> {
        cfg.validate()?;
        let fs = f64::from(cfg.sample_rate);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let var = draw_variation(&mut rng);
        let mut noise_rng = ChaCha8Rng::seed_from_u64(seed ^ 0x9e37_79b9_7f4a_7c15);
        let mut mic_hp = Biquad::default();
        mic_hp.set_highpass(fs, var.mic_highpass_hz, 0.707);
        let wind = OnePole::lowpass(fs, 120.0);
        let wind_norm = 1.0 / (wind.a / (2.0 - wind.a)).sqrt();
        let (rain, car) = match &cfg.noise {
            Some(n) => (
                n.rain.then(|| Rain::new(fs, &mut noise_rng)),
                n.car.then(|| Car::new(fs, &mut noise_rng)),
            ),
            None => (None, None),
        };
        let mut s = Self {
            fs,
            rng,
            noise_rng,
            road: None,
            speed: 0.0,
            speed_target: 0.0,
            glide_a: 1.0 - (-1.0 / (0.003 * fs)).exp(),
            hump: [Biquad::default(); 2],
            hump_norm: 1.0,
            g_hump: Glide::default(),
            texture: Biquad::default(),
            texture_norm: 1.0,
            g_texture: Glide::default(),
            joint_countdown: 0.0,
            thump: Biquad::default(),
            thump_norm: 1.0,
            click_bp: Biquad::default(),
            click_env: 0.0,
            click_decay: (-1.0 / (0.0015 * fs)).exp(),
            click_norm: 1.0,
            g_impact: Glide::default(),
            crunch: Biquad::default(),
            crunch_norm: 1.0,
            g_crunch: Glide::default(),
            ping: Biquad::default(),
            ping_norm: 1.0,
            g_ping: Glide::default(),
            squeak_phase: 0.0,
            squeak_fm: OnePole::lowpass(fs, 4.0),
            squeak_env: 0.0,
            squeak_on: false,
            g_squeak: Glide::default(),
            damping: OnePole::lowpass(fs, 2000.0),
            g_damp: Glide::default(),
            spray_hp: Biquad::default(),
            spray_lp: OnePole::lowpass(fs, 12_000.0f64.min(0.45 * fs)),
            spray_norm: 1.0,
            splash: OnePole::lowpass(fs, 5.0),
            g_spray: Glide::default(),
            g_splash: Glide::default(),
            wind,
            wind_norm,
            g_wind: Glide::default(),
            mic_hp,
            tilt_lp: OnePole::lowpass(fs, 2000.0),
            mic_gain: db(var.mic_gain_db),
            self_noise: db(-75.0),
            noise_cfg: cfg.noise.clone(),
            rain,
            car,
            noise_nominal_power: 1.0,
            road_power_ema: 0.0,
            ema_a: 1.0 - (-1.0 / (1.0 * fs)).exp(),
            var,
        };
        s.noise_nominal_power = s.calibrate_noise();
        Ok(s)
    }

    /// The per-recording parameters drawn from the seed.
    pub fn variation(&self) -> &Variation {
        &self.var
    }

    /// Output sample rate (Hz).
    pub fn sample_rate(&self) -> u32 {
        self.fs as u32
    }

    /// Mean power of the unscaled noise mix over 20 s, measured on a copy of
    /// the noise generators (construction only).
    fn calibrate_noise(&mut self) -> f64 {
        if self.rain.is_none() && self.car.is_none() {
            return 1.0;
        }
        let mut rng = ChaCha8Rng::seed_from_u64(0x5eed_ca1b);
        let mut rain = self.rain.as_ref().map(|_| Rain::new(self.fs, &mut rng));
        let mut car = self.car.as_ref().map(|_| Car::new(self.fs, &mut rng));
        let n = (20.0 * self.fs) as usize;
        let mut p = 0.0;
        for _ in 0..n {
            let mut v = 0.0;
            if let Some(r) = rain.as_mut() {
                v += r.tick(self.fs, &mut rng);
            }
            if let Some(c) = car.as_mut() {
                v += c.tick(self.fs, &mut rng);
            }
            p += v * v;
        }
        (p / n as f64).max(1e-30)
    }

    /// Sets the per-road filters and target gains for (road, speed).
    fn retune(&mut self, road: Option<usize>, v: f64) {
        let fs = self.fs;
        let var = &self.var;
        let vr = (v / V_REF_MPS).max(1e-6);
        let level = |slope: f64| {
            if v <= 0.05 {
                0.0
            } else {
                vr.powf(slope / 20.0)
            }
        };
        let Some(r) = road.filter(|&r| r < ROADS.len()) else {
            for g in [
                &mut self.g_hump,
                &mut self.g_texture,
                &mut self.g_impact,
                &mut self.g_crunch,
                &mut self.g_ping,
                &mut self.g_squeak,
                &mut self.g_spray,
                &mut self.g_wind,
            ] {
                g.target = 0.0;
            }
            return;
        };
        let s = &var.surfaces[r];
        let base = HUMP_RMS * level(var.speed_slope_db);
        // Rolling noise.
        let fh = var.hump_hz * s.hump_freq_factor * vr.powf(var.hump_speed_exp);
        for b in &mut self.hump {
            b.set_bandpass(fs, fh, var.hump_q);
        }
        let mut cascade = self.hump;
        for b in &mut cascade {
            b.z1 = 0.0;
            b.z2 = 0.0;
        }
        let mut e = 0.0;
        let mut probe = cascade;
        for i in 0..4096 {
            let x = if i == 0 { 1.0 } else { 0.0 };
            let y0 = probe[0].tick(x);
            let y = probe[1].tick(y0);
            e += y * y;
        }
        self.hump_norm = 1.0 / e.sqrt().max(1e-12);
        self.g_hump.target = base * db(s.hump_db);
        // Texture band at v / λ_t.
        let ft = (v / s.texture_wavelength_m).clamp(20.0, 0.45 * fs);
        self.texture.set_bandpass(fs, ft, 1.2);
        self.texture_norm = 1.0 / self.texture.white_gain2(4096).sqrt().max(1e-12);
        self.g_texture.target = base * db(s.texture_db);
        // Stone impacts: thump + click, power ≈ (impact level)².
        self.thump.set_resonator(fs, s.thump_hz, s.thump_tau_s);
        self.thump_norm = 1.0
            / self
                .thump
                .white_gain2((0.1 * fs) as usize)
                .sqrt()
                .max(1e-12);
        self.click_bp.set_bandpass(fs, s.click_hz, 1.5);
        let click_e = self.click_bp.white_gain2(2048) / (1.0 - self.click_decay * self.click_decay);
        self.click_norm = 1.0 / click_e.sqrt().max(1e-12);
        self.g_impact.target = if s.impact_db.is_finite() {
            base * db(s.impact_db)
        } else {
            0.0
        };
        // Crunch and pings.
        self.crunch.set_bandpass(fs, s.crunch_hz, 2.0);
        self.crunch_norm = 1.0 / self.crunch.white_gain2(2048).sqrt().max(1e-12);
        self.g_crunch.target = if s.crunch_db.is_finite() {
            base * db(s.crunch_db)
        } else {
            0.0
        };
        self.ping.set_resonator(fs, s.ping_hz, s.ping_tau_s);
        self.ping_norm = 1.0 / self.ping.white_gain2((0.2 * fs) as usize).sqrt().max(1e-12);
        self.g_ping.target = if s.ping_db.is_finite() {
            base * db(s.ping_db)
        } else {
            0.0
        };
        self.g_squeak.target = if s.squeak_db.is_finite() {
            base * db(s.squeak_db)
        } else {
            0.0
        };
        // Surface damping (snow): mix between undamped and one-pole low-pass.
        if let Some(fd) = s.damping_hz {
            self.damping.set(fs, fd);
            self.g_damp.target = 1.0;
        } else {
            self.g_damp.target = 0.0;
        }
        // Spray: grows 10 dB/decade faster with speed than rolling noise.
        self.spray_hp.set_highpass(fs, s.spray_hz, 0.707);
        self.spray_norm = 1.0 / self.spray_hp.white_gain2(2048).sqrt().max(1e-12);
        self.g_spray.target = if s.spray_db.is_finite() {
            HUMP_RMS * level(var.speed_slope_db + 10.0) * db(s.spray_db)
        } else {
            0.0
        };
        self.g_splash.target = s.splash_mod;
        // Wind rumble ∝ v³.
        self.g_wind.target = HUMP_RMS * db(var.wind_db) * vr.powi(3);
    }

    /// Fills `out` with the microphone signal (road sound plus the configured
    /// noise at the configured SNR) for `road` (index into [`ROADS`]) at
    /// `speed_mps`. Continues seamlessly from the previous call; a changed
    /// road or speed takes effect at the first sample (gains glide over
    /// ≈ 3 ms, so the change is abrupt but click-free). An out-of-range road
    /// index gives the vehicle and microphone sound only (no tyre-road
    /// sound); a non-finite or negative speed counts as 0. Output is clamped
    /// to [−1, 1]. Allocates nothing.
    ///
    /// In streaming use the noise level follows a 1 s running estimate of the
    /// road-sound power; [`render`] scales it exactly over a recording.
    pub fn fill(&mut self, road: usize, speed_mps: f64, out: &mut [f32]) {
        let snr_gain = self.noise_cfg.as_ref().map(|n| db(-n.snr_db));
        self.run(
            road,
            speed_mps,
            out.len(),
            |i, road_s, noise_s, ema, nominal| {
                let mut v = road_s;
                if let Some(g) = snr_gain {
                    v += noise_s * g * (ema / nominal).sqrt();
                }
                out[i] = v.clamp(-1.0, 1.0) as f32;
            },
        );
    }

    /// Like [`Self::fill`] but writes the road sound and the unscaled noise
    /// mix (nominal unit power) separately; neither is clamped.
    pub fn fill_parts(
        &mut self,
        road: usize,
        speed_mps: f64,
        road_out: &mut [f32],
        noise_out: &mut [f32],
    ) {
        let n = road_out.len().min(noise_out.len());
        self.run(road, speed_mps, n, |i, road_s, noise_s, _, nominal| {
            road_out[i] = road_s as f32;
            noise_out[i] = (noise_s / nominal.sqrt()) as f32;
        });
    }

    fn run(
        &mut self,
        road: usize,
        speed_mps: f64,
        n: usize,
        mut sink: impl FnMut(usize, f64, f64, f64, f64),
    ) {
        let speed = if speed_mps.is_finite() {
            speed_mps.clamp(0.0, 80.0)
        } else {
            0.0
        };
        let road_opt = (road < ROADS.len()).then_some(road);
        if road_opt != self.road || (speed - self.speed_target).abs() > 1e-9 {
            let first = self.road.is_none() && self.speed_target == 0.0 && self.speed == 0.0;
            self.road = road_opt;
            self.speed_target = speed;
            if first {
                self.speed = speed;
            }
        }
        let fs = self.fs;
        let nominal = self.noise_nominal_power;
        // Speed glides with 50 ms; filters are retuned every 256 samples.
        let sp_a = 1.0 - (-1.0 / (0.05 * fs)).exp();
        let mut since_retune = usize::MAX;
        let start_fill =
            self.g_hump.v == 0.0 && self.g_hump.target == 0.0 && self.road_power_ema == 0.0;
        for i in 0..n {
            if since_retune >= 256 {
                self.speed += (self.speed_target - self.speed) * (1.0 - (1.0 - sp_a).powi(256));
                if (self.speed - self.speed_target).abs() < 1e-3 {
                    self.speed = self.speed_target;
                }
                self.retune(self.road, self.speed);
                if start_fill && i == 0 {
                    // First call: start at the target gains (no fade-in).
                    for g in [
                        &mut self.g_hump,
                        &mut self.g_texture,
                        &mut self.g_impact,
                        &mut self.g_crunch,
                        &mut self.g_ping,
                        &mut self.g_squeak,
                        &mut self.g_damp,
                        &mut self.g_spray,
                        &mut self.g_splash,
                        &mut self.g_wind,
                    ] {
                        g.v = g.target;
                    }
                }
                since_retune = 0;
            }
            since_retune += 1;
            let road_s = self.road_sample();
            let mut noise_s = 0.0;
            if let Some(r) = self.rain.as_mut() {
                noise_s += r.tick(fs, &mut self.noise_rng);
            }
            if let Some(c) = self.car.as_mut() {
                noise_s += c.tick(fs, &mut self.noise_rng);
            }
            if start_fill && i == 0 {
                self.road_power_ema = road_s * road_s + 1e-12;
            }
            self.road_power_ema += self.ema_a * (road_s * road_s - self.road_power_ema);
            sink(i, road_s, noise_s, self.road_power_ema, nominal);
        }
    }

    #[inline]
    fn road_sample(&mut self) -> f64 {
        let fs = self.fs;
        let a = self.glide_a;
        let r = self.road.unwrap_or(0);
        let s = &self.var.surfaces[r];
        let v = self.speed;
        let rng = &mut self.rng;
        // Rolling noise.
        let g = self.g_hump.tick(a);
        let w = gauss(rng);
        let h0 = self.hump[0].tick(w);
        let mut y = g * self.hump_norm * self.hump[1].tick(h0);
        // Texture.
        let g = self.g_texture.tick(a);
        y += g * self.texture_norm * self.texture.tick(gauss(rng));
        // Stone joints: impacts at v / L with jitter; power-normalised so the
        // mean impact power equals g².
        let g = self.g_impact.tick(a);
        let mut exc = 0.0;
        if self.g_impact.target > 0.0 && v > 0.1 {
            self.joint_countdown -= 1.0;
            if self.joint_countdown <= 0.0 {
                let period = s.sett_length_m / v * fs;
                self.joint_countdown += period * (1.0 + s.sett_jitter * gauss(rng)).max(0.2);
                exc = (0.35 * gauss(rng) - 0.1225).exp() * period.sqrt();
            }
        }
        if exc != 0.0 {
            self.click_env += exc;
        }
        let thump = self.thump.tick(exc) * self.thump_norm;
        let click = self.click_bp.tick(gauss(rng)) * self.click_env * self.click_norm;
        self.click_env *= self.click_decay;
        y += g * std::f64::consts::FRAC_1_SQRT_2 * (thump + click);
        // Crunch: Poisson events at v · density, random sign.
        let g = self.g_crunch.tick(a);
        let mut cx = 0.0;
        let rate = v * s.crunch_per_m;
        if self.g_crunch.target > 0.0 && rate > 0.0 && rng.random::<f64>() < rate / fs {
            let sign = if rng.random::<bool>() { 1.0 } else { -1.0 };
            cx = sign * (0.6 * gauss(rng) - 0.36).exp() * (fs / rate).sqrt();
        }
        y += g * self.crunch.tick(cx) * self.crunch_norm;
        // Pings (stone throws on the wheel arch).
        let g = self.g_ping.tick(a);
        let mut px = 0.0;
        let rate = v * s.ping_per_m;
        if self.g_ping.target > 0.0 && rate > 0.0 && rng.random::<f64>() < rate / fs {
            px = (0.5 * gauss(rng) - 0.25).exp() * (fs / rate).sqrt();
        }
        y += g * self.ping.tick(px) * self.ping_norm;
        // Snow squeak: tone bursts (mean on 40 ms, off 160 ms) with slow FM.
        let g = self.g_squeak.tick(a);
        if self.g_squeak.target > 0.0 || g > 1e-9 {
            let flip = if self.squeak_on {
                1.0 / (0.04 * fs)
            } else {
                1.0 / (0.16 * fs)
            };
            if rng.random::<f64>() < flip {
                self.squeak_on = !self.squeak_on;
            }
            let target = if self.squeak_on { 1.0 } else { 0.0 };
            self.squeak_env += (target - self.squeak_env) * (1.0 / (0.004 * fs));
            let fm = self.squeak_fm.tick(gauss(rng)) * 30.0;
            self.squeak_phase += 2.0 * PI * (s.squeak_hz * (1.0 + 0.05 * fm)) / fs;
            if self.squeak_phase > 2.0 * PI {
                self.squeak_phase -= 2.0 * PI;
            }
            // ≈ 20 % duty: scale so the mean power is g².
            y += g * 2.2 * self.squeak_env * self.squeak_phase.sin();
        }
        // Surface damping (snow).
        let gd = self.g_damp.tick(a);
        let damped = self.damping.tick(y);
        y = gd * damped + (1.0 - gd) * y;
        // Water-film spray hiss with slow splash modulation.
        let g = self.g_spray.tick(a);
        let m = self.g_splash.tick(a);
        let splash = self.splash.tick(gauss(rng)) * (2.0 * fs / (2.0 * PI * 5.0)).sqrt();
        let hiss = self.spray_lp.tick(self.spray_hp.tick(gauss(rng))) * self.spray_norm;
        y += g * (1.0 + m * splash.clamp(-2.5, 2.5)) / (1.0 + m * m).sqrt() * hiss;
        // Wind rumble.
        let g = self.g_wind.tick(a);
        y += g * self.wind_norm * self.wind.tick(gauss(rng));
        // Microphone: high-pass, high-shelf tilt, gain, self-noise.
        let x = self.mic_hp.tick(y);
        let low = self.tilt_lp.tick(x);
        let x = x + self.var.mic_tilt * (x - low);
        x * self.mic_gain + self.self_noise * gauss(rng)
    }
}

/// One stretch of a recording on one road at one speed.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Segment {
    /// Road class index into [`ROADS`].
    pub road: usize,
    /// Vehicle speed (m/s).
    pub speed_mps: f64,
    /// Duration (s).
    pub duration_s: f64,
}

/// Over what the SNR of a rendered recording is defined.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SnrScope {
    /// Road-sound power over the whole recording / noise power over the
    /// whole recording: the noise has one level, so a quiet road (snow) in a
    /// recording with loud ones (stone, gravel) sits below the nominal SNR.
    #[default]
    Recording,
    /// Every segment at the nominal SNR against the noise power over the
    /// whole recording: the noise gain is set per segment from that
    /// segment's road-sound power (ramped over 3 ms at the boundaries), so
    /// each road gets the noise level a one-road recording of it would get.
    /// (Not the segment's own noise power: in a 1–3 s segment that depends on
    /// whether a car happens to pass, and scaling to it would turn the rain
    /// up whenever none does.)
    Segment,
    /// As in the loop ([`RoadAudioSynth::fill`]: `grip sim --arte acoustic`,
    /// audio-acq's synthetic source): the noise at the nominal SNR against a
    /// 1 s running estimate of the road-sound power, so for about a second
    /// after a loud road a quiet one (snow) sits under noise pitched for the
    /// loud one, as a real microphone would hear it.
    Running,
}

/// Renders a whole recording (segments back to back, abrupt road changes at
/// the segment boundaries). With noise configured, the noise mix is scaled
/// so that the road-sound power over the whole recording divided by the
/// noise power over the whole recording equals the SNR exactly; then the
/// sum is clamped to [−1, 1]. Allocates the output.
pub fn render(cfg: &SynthConfig, seed: u64, segments: &[Segment]) -> Result<Vec<f32>, SynthError> {
    render_scoped(cfg, seed, segments, SnrScope::Recording)
}

/// [`render`] with the SNR defined over the whole recording or per segment
/// ([`SnrScope`]). For one segment both scopes give identical samples.
pub fn render_scoped(
    cfg: &SynthConfig,
    seed: u64,
    segments: &[Segment],
    scope: SnrScope,
) -> Result<Vec<f32>, SynthError> {
    let mut synth = RoadAudioSynth::new(cfg, seed)?;
    let fs = f64::from(cfg.sample_rate);
    let mut lens = Vec::with_capacity(segments.len());
    for (index, s) in segments.iter().enumerate() {
        if s.road >= ROADS.len() {
            return Err(SynthError::InvalidSegment {
                index,
                reason: format!("road index {} is not below {}", s.road, ROADS.len()),
            });
        }
        if !(s.speed_mps >= 0.0 && s.speed_mps <= 80.0) {
            return Err(SynthError::InvalidSegment {
                index,
                reason: format!("speed {} m/s is outside 0..=80", s.speed_mps),
            });
        }
        if !(s.duration_s > 0.0 && s.duration_s <= 3600.0) {
            return Err(SynthError::InvalidSegment {
                index,
                reason: format!("duration {} s is outside (0, 3600]", s.duration_s),
            });
        }
        lens.push((s.duration_s * fs).round() as usize);
    }
    let total: usize = lens.iter().sum();
    let per_segment = match scope {
        SnrScope::Recording => false,
        SnrScope::Segment => true,
        SnrScope::Running => {
            let mut out = vec![0f32; total];
            let mut at = 0;
            for (s, &n) in segments.iter().zip(&lens) {
                synth.fill(s.road, s.speed_mps, &mut out[at..at + n]);
                at += n;
            }
            return Ok(out);
        }
    };
    let mut road = vec![0f32; total];
    let mut noise = vec![0f32; total];
    let mut at = 0;
    for (s, &n) in segments.iter().zip(&lens) {
        synth.fill_parts(
            s.road,
            s.speed_mps,
            &mut road[at..at + n],
            &mut noise[at..at + n],
        );
        at += n;
    }
    let Some(nc) = &cfg.noise else {
        return Ok(road.into_iter().map(|v| v.clamp(-1.0, 1.0)).collect());
    };
    let power = |x: &[f32]| -> f64 {
        x.iter().map(|&v| f64::from(v) * f64::from(v)).sum::<f64>() / x.len().max(1) as f64
    };
    let gain = |p_road: f64, p_noise: f64| -> f64 {
        if p_noise > 0.0 {
            (p_road / p_noise * db(-nc.snr_db).powi(2)).sqrt()
        } else {
            0.0
        }
    };
    // Noise gain per sample: one value, or one per segment ramped over 3 ms.
    let mut gains = Vec::with_capacity(lens.len());
    if !per_segment {
        gains.resize(lens.len(), gain(power(&road), power(&noise)));
    } else {
        // Against the noise power over the whole recording: this
        // recording's rain and cars (their parameters are drawn per
        // recording, so their level is not the calibrated nominal one).
        let p_noise = power(&noise);
        let mut at = 0;
        for &n in &lens {
            gains.push(gain(power(&road[at..at + n]), p_noise));
            at += n;
        }
    }
    let ramp = ((0.003 * fs).round() as usize).max(1);
    let mut out = Vec::with_capacity(total);
    let mut at = 0;
    for (i, &n) in lens.iter().enumerate() {
        let (g0, g1) = (if i == 0 { gains[0] } else { gains[i - 1] }, gains[i]);
        for j in 0..n {
            let g = if j < ramp {
                g0 + (g1 - g0) * (j + 1) as f64 / ramp as f64
            } else {
                g1
            };
            let v = f64::from(road[at + j]) + g * f64::from(noise[at + j]);
            out.push(v.clamp(-1.0, 1.0) as f32);
        }
        at += n;
    }
    Ok(out)
}
