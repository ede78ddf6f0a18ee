//! JSON mapping of the grip payloads for MCAP (`message_encoding = "json"`,
//! schema encoding `jsonschema`), so Foxglove and the official readers can
//! read the logs. grip-msgs has no serde; the mapping lives here.
//!
//! Exactness: integers are written as JSON integers (u64 exact), floats with
//! Rust's shortest round-trip representation (`{:?}`), f32 widened to f64
//! (exact), non-finite floats as `null` (read back as NaN). Fixed name
//! fields are written as strings (text up to the first zero byte) and audio
//! as the first `n_samples` samples; both read back exactly when the unused
//! bytes/samples are zero, which is how the producers fill them.

use std::io::Write;

use grip_msgs::{
    AUDIO_MAX_SAMPLES, AudioBlock, BusFrame, CanFrame, CycleRecord, E2eFaults, GroundTruth,
    MAX_ROAD_CLASSES, NAME_LEN, RoadEstimate, name_from_bytes, name_to_bytes,
};
use serde_json::{Value, json};

/// A JSON field was missing or had the wrong type or range.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{schema}: field {field:?}: {reason}")]
pub struct JsonError {
    /// Schema name.
    pub schema: &'static str,
    /// Field.
    pub field: &'static str,
    /// Why.
    pub reason: String,
}

/// A payload that can be logged to MCAP as JSON.
pub trait McapRecord: Sized {
    /// Schema name (= the versioned iceoryx2 type name).
    const SCHEMA_NAME: &'static str;
    /// JSON Schema of the encoding.
    fn json_schema() -> Value;
    /// Appends the JSON encoding to `out`.
    fn write_json(&self, out: &mut Vec<u8>);
    /// Parses the JSON encoding.
    fn from_json(v: &Value) -> Result<Self, JsonError>;
    /// The payload's own time stamp (used as MCAP log time).
    fn stamp_ns(&self) -> u64;
}

// ----------------------------------------------------------- writing ----

struct Obj<'a> {
    out: &'a mut Vec<u8>,
    first: bool,
}

impl<'a> Obj<'a> {
    fn new(out: &'a mut Vec<u8>) -> Self {
        out.push(b'{');
        Self { out, first: true }
    }
    fn key(&mut self, k: &str) {
        if !self.first {
            self.out.push(b',');
        }
        self.first = false;
        self.out.push(b'"');
        self.out.extend_from_slice(k.as_bytes());
        self.out.extend_from_slice(b"\":");
    }
    fn u(&mut self, k: &str, v: u64) -> &mut Self {
        self.key(k);
        let _ = write!(self.out, "{v}");
        self
    }
    fn i(&mut self, k: &str, v: i64) -> &mut Self {
        self.key(k);
        let _ = write!(self.out, "{v}");
        self
    }
    fn f(&mut self, k: &str, v: f64) -> &mut Self {
        self.key(k);
        put_f64(self.out, v);
        self
    }
    fn s(&mut self, k: &str, v: &str) -> &mut Self {
        self.key(k);
        // serde_json escapes correctly; a string write into a Vec cannot fail
        let _ = serde_json::to_writer(&mut *self.out, v);
        self
    }
    fn arr<T: Copy>(
        &mut self,
        k: &str,
        v: &[T],
        mut put: impl FnMut(&mut Vec<u8>, T),
    ) -> &mut Self {
        self.key(k);
        self.out.push(b'[');
        for (i, &x) in v.iter().enumerate() {
            if i > 0 {
                self.out.push(b',');
            }
            put(self.out, x);
        }
        self.out.push(b']');
        self
    }
    fn obj(&mut self, k: &str, f: impl FnOnce(&mut Obj<'_>)) -> &mut Self {
        self.key(k);
        let mut o = Obj::new(self.out);
        f(&mut o);
        o.end();
        self
    }
    fn end(&mut self) {
        self.out.push(b'}');
    }
}

fn put_f64(out: &mut Vec<u8>, v: f64) {
    if v.is_finite() {
        let _ = write!(out, "{v:?}");
    } else {
        out.extend_from_slice(b"null");
    }
}

// ----------------------------------------------------------- reading ----

struct Rd<'a> {
    v: &'a Value,
    schema: &'static str,
}

impl<'a> Rd<'a> {
    fn err(&self, field: &'static str, reason: impl Into<String>) -> JsonError {
        JsonError {
            schema: self.schema,
            field,
            reason: reason.into(),
        }
    }
    fn get(&self, k: &'static str) -> Result<&'a Value, JsonError> {
        self.v.get(k).ok_or_else(|| self.err(k, "missing"))
    }
    fn u64(&self, k: &'static str) -> Result<u64, JsonError> {
        self.get(k)?
            .as_u64()
            .ok_or_else(|| self.err(k, "not an unsigned integer"))
    }
    fn uint<T: TryFrom<u64>>(&self, k: &'static str) -> Result<T, JsonError> {
        T::try_from(self.u64(k)?).map_err(|_| self.err(k, "out of range"))
    }
    fn i64(&self, k: &'static str) -> Result<i64, JsonError> {
        self.get(k)?
            .as_i64()
            .ok_or_else(|| self.err(k, "not an integer"))
    }
    fn f64(&self, k: &'static str) -> Result<f64, JsonError> {
        let v = self.get(k)?;
        if v.is_null() {
            return Ok(f64::NAN);
        }
        v.as_f64().ok_or_else(|| self.err(k, "not a number"))
    }
    fn name(&self, k: &'static str) -> Result<[u8; NAME_LEN], JsonError> {
        let s = self
            .get(k)?
            .as_str()
            .ok_or_else(|| self.err(k, "not a string"))?;
        if s.len() > NAME_LEN {
            return Err(self.err(k, format!("longer than {NAME_LEN} bytes")));
        }
        Ok(name_to_bytes(s))
    }
    /// The 8 data bytes of a CAN frame's `data` (`CanFrame`, `BusFrame`).
    fn data8(&self) -> Result<[u8; 8], JsonError> {
        let d = self.array("data", 8)?;
        if d.len() != 8 {
            return Err(self.err("data", "must have 8 bytes"));
        }
        let mut data = [0u8; 8];
        for (o, x) in data.iter_mut().zip(d) {
            *o = x
                .as_u64()
                .and_then(|x| u8::try_from(x).ok())
                .ok_or_else(|| self.err("data", "byte out of range"))?;
        }
        Ok(data)
    }

    fn array(&self, k: &'static str, max: usize) -> Result<&'a Vec<Value>, JsonError> {
        let a = self
            .get(k)?
            .as_array()
            .ok_or_else(|| self.err(k, "not an array"))?;
        if a.len() > max {
            return Err(self.err(k, format!("{} elements, at most {max}", a.len())));
        }
        Ok(a)
    }
    fn sub(&self, k: &'static str) -> Result<Rd<'a>, JsonError> {
        let v = self.get(k)?;
        if !v.is_object() {
            return Err(self.err(k, "not an object"));
        }
        Ok(Rd {
            v,
            schema: self.schema,
        })
    }
}

fn root<'a>(v: &'a Value, schema: &'static str) -> Result<Rd<'a>, JsonError> {
    if !v.is_object() {
        return Err(JsonError {
            schema,
            field: "",
            reason: "message is not a JSON object".into(),
        });
    }
    Ok(Rd { v, schema })
}

// ----------------------------------------------------------- schemas ----

fn schema(title: &str, description: &str, props: &[(&str, Value)]) -> Value {
    let mut p = serde_json::Map::new();
    let mut req = Vec::new();
    for (k, v) in props {
        p.insert((*k).to_string(), v.clone());
        req.push(Value::String((*k).to_string()));
    }
    json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": title,
        "description": description,
        "type": "object",
        "properties": p,
        "required": req,
    })
}
fn t_int(d: &str) -> Value {
    json!({"type": "integer", "description": d})
}
fn t_num(d: &str) -> Value {
    json!({"type": ["number", "null"], "description": d})
}
fn t_str(d: &str) -> Value {
    json!({"type": "string", "description": d})
}
fn t_arr(item: &str, max: usize, d: &str) -> Value {
    json!({"type": "array", "items": {"type": item}, "maxItems": max, "description": d})
}

fn faults_schema() -> Value {
    schema(
        "E2eFaults",
        "E2E receive fault counters of tcs-loop since its start, all received messages summed (u32, wrapping)",
        &[
            ("crc", t_int("frames whose CRC did not match")),
            (
                "counter_repeated",
                t_int("frames whose alive counter repeated the previous one"),
            ),
            (
                "counter_skipped",
                t_int("frames whose alive counter jumped (frames lost in between)"),
            ),
            ("length", t_int("frames with the wrong DLC")),
            (
                "unknown_id",
                t_int("frames with an identifier the protocol does not know"),
            ),
            (
                "timeout",
                t_int("timeout episodes: a message stayed away longer than its timeout"),
            ),
        ],
    )
}

fn write_faults(o: &mut Obj<'_>, f: &E2eFaults) {
    o.u("crc", f.crc.into())
        .u("counter_repeated", f.counter_repeated.into())
        .u("counter_skipped", f.counter_skipped.into())
        .u("length", f.length.into())
        .u("unknown_id", f.unknown_id.into())
        .u("timeout", f.timeout.into());
}

fn read_faults(r: &Rd<'_>) -> Result<E2eFaults, JsonError> {
    Ok(E2eFaults {
        crc: r.uint("crc")?,
        counter_repeated: r.uint("counter_repeated")?,
        counter_skipped: r.uint("counter_skipped")?,
        length: r.uint("length")?,
        unknown_id: r.uint("unknown_id")?,
        timeout: r.uint("timeout")?,
    })
}

// -------------------------------------------------------------- types ----

impl McapRecord for AudioBlock {
    const SCHEMA_NAME: &'static str = AudioBlock::TYPE_NAME;
    fn json_schema() -> Value {
        schema(
            Self::SCHEMA_NAME,
            "Block of mono 16-bit PCM from the tyre microphone (audio-acq), which sits the vehicle file's mic_lead_m ahead of the driven wheel",
            &[
                (
                    "seq",
                    t_int("block sequence number, +1 per block (a gap = blocks lost)"),
                ),
                (
                    "stamp_ns",
                    t_int("CLOCK_MONOTONIC time of the first sample, ns"),
                ),
                ("sample_rate", t_int("sample rate, Hz")),
                (
                    "n_samples",
                    t_int("number of valid samples: the length of samples"),
                ),
                (
                    "channel",
                    t_int("capture channel the block came from, 0-based"),
                ),
                (
                    "xruns",
                    t_int("capture overruns counted since audio-acq started"),
                ),
                (
                    "samples",
                    t_arr(
                        "integer",
                        AUDIO_MAX_SAMPLES,
                        "signed 16-bit PCM, n_samples of them (full scale 32768)",
                    ),
                ),
            ],
        )
    }
    fn write_json(&self, out: &mut Vec<u8>) {
        let mut o = Obj::new(out);
        o.u("seq", self.seq)
            .u("stamp_ns", self.stamp_ns)
            .u("sample_rate", self.sample_rate.into())
            // the samples written: a publisher's n_samples above the
            // block's capacity (another process's data) would otherwise
            // give a record its own reader refuses
            .u("n_samples", self.samples().len() as u64)
            .u("channel", self.channel.into())
            .u("xruns", self.xruns.into())
            .arr("samples", self.samples(), |b, x| {
                let _ = write!(b, "{x}");
            });
        o.end();
    }
    fn from_json(v: &Value) -> Result<Self, JsonError> {
        let r = root(v, Self::SCHEMA_NAME)?;
        let mut a = AudioBlock::zeroed();
        a.seq = r.u64("seq")?;
        a.stamp_ns = r.u64("stamp_ns")?;
        a.sample_rate = r.uint("sample_rate")?;
        a.n_samples = r.uint("n_samples")?;
        a.channel = r.uint("channel")?;
        a.xruns = r.uint("xruns")?;
        let s = r.array("samples", AUDIO_MAX_SAMPLES)?;
        if s.len() != a.n_samples as usize {
            return Err(r.err(
                "samples",
                format!("{} samples but n_samples = {}", s.len(), a.n_samples),
            ));
        }
        for (d, x) in a.samples.iter_mut().zip(s) {
            *d = x
                .as_i64()
                .and_then(|x| i16::try_from(x).ok())
                .ok_or_else(|| r.err("samples", "sample is not an i16"))?;
        }
        Ok(a)
    }
    fn stamp_ns(&self) -> u64 {
        self.stamp_ns
    }
}

impl McapRecord for RoadEstimate {
    const SCHEMA_NAME: &'static str = RoadEstimate::TYPE_NAME;
    fn json_schema() -> Value {
        schema(
            Self::SCHEMA_NAME,
            "Acoustic road-type estimate of arte for one audio frame. Class indices count in the model's class list (the classes of the model file attached under models/), not in roads.toml",
            &[
                ("seq", t_int("decision sequence number, +1 per estimate")),
                (
                    "stamp_ns",
                    t_int("CLOCK_MONOTONIC time arte published the estimate, ns"),
                ),
                (
                    "frame_t0_ns",
                    t_int("CLOCK_MONOTONIC time of the audio frame's start, ns"),
                ),
                (
                    "frame_t1_ns",
                    t_int("CLOCK_MONOTONIC time of the audio frame's end, ns"),
                ),
                (
                    "class_index",
                    t_int(
                        "winning class, an index into the model's class list; 4294967295 = none (audio not classified: silence, clipping, overruns)",
                    ),
                ),
                (
                    "n_classes",
                    t_int("number of the model's classes: valid entries of probabilities"),
                ),
                (
                    "class_name",
                    t_str(
                        "name of the winning class (a roads.toml road name); empty with no class",
                    ),
                ),
                (
                    "probabilities",
                    t_arr(
                        "number",
                        MAX_ROAD_CLASSES,
                        "smoothed class probabilities in the model's class order (entry i = class_index i); entries from n_classes on are 0, all are 0 with no class",
                    ),
                ),
                (
                    "confidence",
                    t_num("smoothed probability of the winning class, 0..1; 0 with no class"),
                ),
                (
                    "lambda_opt",
                    t_num(
                        "optimal slip of the winning class's road curve in roads.toml; null with no class",
                    ),
                ),
                (
                    "mu_peak",
                    t_num("peak friction coefficient of that road's curve; null with no class"),
                ),
                (
                    "alpha",
                    t_num(
                        "MTTE relaxation factor of that road: arte-svc.toml [knowledge] alpha, else 1 - lambda_opt; null with no class",
                    ),
                ),
                (
                    "x_from",
                    t_num(
                        "tcs-loop's odometer (CycleRecord odometer, m) at frame_t0_ns, extrapolated by arte; the heard road lies mic_lead_m further on. null without a fresh cycle record with valid v",
                    ),
                ),
                (
                    "x_to",
                    t_num("tcs-loop's odometer at frame_t1_ns, m; null as x_from"),
                ),
            ],
        )
    }
    fn write_json(&self, out: &mut Vec<u8>) {
        let mut o = Obj::new(out);
        o.u("seq", self.seq)
            .u("stamp_ns", self.stamp_ns)
            .u("frame_t0_ns", self.frame_t0_ns)
            .u("frame_t1_ns", self.frame_t1_ns)
            .u("class_index", self.class_index.into())
            .u("n_classes", self.n_classes.into())
            .s(
                "class_name",
                name_from_bytes(&self.class_name).unwrap_or(""),
            )
            .arr("probabilities", &self.probabilities, |b, x| {
                put_f64(b, f64::from(x))
            })
            .f("confidence", self.confidence)
            .f("lambda_opt", self.lambda_opt)
            .f("mu_peak", self.mu_peak)
            .f("alpha", self.alpha)
            .f("x_from", self.x_from)
            .f("x_to", self.x_to);
        o.end();
    }
    fn from_json(v: &Value) -> Result<Self, JsonError> {
        let r = root(v, Self::SCHEMA_NAME)?;
        let mut e = RoadEstimate::zeroed();
        e.seq = r.u64("seq")?;
        e.stamp_ns = r.u64("stamp_ns")?;
        e.frame_t0_ns = r.u64("frame_t0_ns")?;
        e.frame_t1_ns = r.u64("frame_t1_ns")?;
        e.class_index = r.uint("class_index")?;
        e.n_classes = r.uint("n_classes")?;
        e.class_name = r.name("class_name")?;
        let p = r.array("probabilities", MAX_ROAD_CLASSES)?;
        for (d, x) in e.probabilities.iter_mut().zip(p) {
            *d = if x.is_null() {
                f32::NAN
            } else {
                x.as_f64()
                    .ok_or_else(|| r.err("probabilities", "not a number"))? as f32
            };
        }
        e.confidence = r.f64("confidence")?;
        e.lambda_opt = r.f64("lambda_opt")?;
        e.mu_peak = r.f64("mu_peak")?;
        e.alpha = r.f64("alpha")?;
        e.x_from = r.f64("x_from")?;
        e.x_to = r.f64("x_to")?;
        Ok(e)
    }
    fn stamp_ns(&self) -> u64 {
        self.stamp_ns
    }
}

impl McapRecord for CycleRecord {
    const SCHEMA_NAME: &'static str = CycleRecord::TYPE_NAME;
    fn json_schema() -> Value {
        schema(
            Self::SCHEMA_NAME,
            "One tcs-loop control cycle. Torques are N m at ONE driven wheel, after the gear (the unit of the vehicle file's torque_max); null = NaN",
            &[
                (
                    "seq",
                    t_int("cycle number, from 0 at tcs-loop's start, +1 per cycle"),
                ),
                (
                    "stamp_ns",
                    t_int("CLOCK_MONOTONIC time of the cycle's deadline (its nominal start), ns"),
                ),
                (
                    "wakeup_latency_ns",
                    t_int("wake-up time minus deadline, ns"),
                ),
                (
                    "compute_ns",
                    t_int("wake-up to command sent and the cycle's CAN frames logged, ns"),
                ),
                (
                    "deadline_misses",
                    t_int("deadline misses counted since tcs-loop started"),
                ),
                (
                    "omega",
                    t_num(
                        "measured driven-wheel speed (WheelSpeeds OmegaDriven), rad/s; 0 without a fresh valid frame",
                    ),
                ),
                (
                    "v",
                    t_num(
                        "measured vehicle speed, m/s: r_ref times OmegaRef when RefValid, else VehicleSpeed Speed; null when v_valid = 0",
                    ),
                ),
                (
                    "torque",
                    t_num(
                        "torque the inverter reports (MotorStatus TorqueActual), N m at one driven wheel; 0 before the first frame",
                    ),
                ),
                (
                    "demand",
                    t_num(
                        "driver demand T_d (DriverDemand TorqueDemand), N m at one driven wheel; 0 while BrakePressed and before the first frame",
                    ),
                ),
                (
                    "torque_cmd",
                    t_num(
                        "torque command T* sent this cycle (TorqueCommand TorqueRequest), N m at one driven wheel: 0 in the safe state, the demand when TcsEnable = 0, else the controller's command limited to torque_cap",
                    ),
                ),
                (
                    "internal",
                    t_num(
                        "controller signal, by controller: MFC model wheel speed omega_M (rad/s), SRC slip reference lambda* (no unit), MTTE torque limit T_max (N m, one driven wheel); null in the safe state",
                    ),
                ),
                (
                    "mu_hat",
                    t_num(
                        "friction in use (observed tyre force / wheel load) of SRC and MTTE, null for MFC and in the safe state; not the road's peak friction, and overstated by MTTE with ARTE while torque_cap binds",
                    ),
                ),
                (
                    "odometer",
                    t_num(
                        "tcs-loop's odometer at the cycle's start, m: forward travel from measured v (else r times omega) since tcs-loop started; its origin is not the ground truth's x = 0",
                    ),
                ),
                (
                    "torque_cap",
                    t_num(
                        "cap the road knowledge put on the command this cycle, N m at one driven wheel; null = no cap (ARTE off, safe state, no estimate within [arte] max_age_s, or none applies)",
                    ),
                ),
                (
                    "belief_prob",
                    t_num(
                        "probability of belief_road in the road belief; null with ARTE off and in the safe state",
                    ),
                ),
                (
                    "road_class",
                    t_int(
                        "class_index of the newest road estimate taken (model's class list; the road heard at the microphone, not the one under the wheel), set only when used_arte = 1; 4294967295 = none",
                    ),
                ),
                (
                    "belief_road",
                    t_int(
                        "road the loop believes is under the driven wheel, an index into roads.toml's road list (ARTE on); 4294967295 with ARTE off and in the safe state",
                    ),
                ),
                (
                    "used_arte",
                    t_int(
                        "1 = the controller used the believed road's knowledge: an estimate with a class within [arte] max_age_s and belief_prob at least [arte] min_confidence (controllers.toml); torque_cap acts without it",
                    ),
                ),
                (
                    "safe_state",
                    t_int(
                        "1 = safe state (inputs missing or stale, inverter fault, or recovering): command 0 N m with Enable cleared, controller not stepped",
                    ),
                ),
                ("v_valid", t_int("1 = v holds a valid measurement")),
                ("faults", faults_schema()),
                (
                    "road_taken",
                    t_int(
                        "1 + low 32 bits of the seq of the newest road estimate taken this cycle, 0 = none",
                    ),
                ),
                (
                    "roads_taken",
                    t_int(
                        "road estimates taken this cycle from grip/arte/road, in order (absent in older logs; 0 in logs from before the count)",
                    ),
                ),
            ],
        )
    }
    fn write_json(&self, out: &mut Vec<u8>) {
        let mut o = Obj::new(out);
        o.u("seq", self.seq)
            .u("stamp_ns", self.stamp_ns)
            .i("wakeup_latency_ns", self.wakeup_latency_ns)
            .u("compute_ns", self.compute_ns)
            .u("deadline_misses", self.deadline_misses)
            .f("omega", self.omega)
            .f("v", self.v)
            .f("torque", self.torque)
            .f("demand", self.demand)
            .f("torque_cmd", self.torque_cmd)
            .f("internal", self.internal)
            .f("mu_hat", self.mu_hat)
            .f("odometer", self.odometer)
            .f("torque_cap", self.torque_cap)
            .f("belief_prob", self.belief_prob)
            .u("road_class", self.road_class.into())
            .u("belief_road", self.belief_road.into())
            .u("used_arte", self.used_arte.into())
            .u("safe_state", self.safe_state.into())
            .u("v_valid", self.v_valid.into())
            .obj("faults", |o| write_faults(o, &self.faults))
            .u("road_taken", self.road_taken.into())
            .u("roads_taken", self.roads_taken.into());
        o.end();
    }
    fn from_json(v: &Value) -> Result<Self, JsonError> {
        let r = root(v, Self::SCHEMA_NAME)?;
        Ok(CycleRecord {
            seq: r.u64("seq")?,
            stamp_ns: r.u64("stamp_ns")?,
            wakeup_latency_ns: r.i64("wakeup_latency_ns")?,
            compute_ns: r.u64("compute_ns")?,
            deadline_misses: r.u64("deadline_misses")?,
            omega: r.f64("omega")?,
            v: r.f64("v")?,
            torque: r.f64("torque")?,
            demand: r.f64("demand")?,
            torque_cmd: r.f64("torque_cmd")?,
            internal: r.f64("internal")?,
            mu_hat: r.f64("mu_hat")?,
            odometer: r.f64("odometer")?,
            torque_cap: r.f64("torque_cap")?,
            belief_prob: r.f64("belief_prob")?,
            road_class: r.uint("road_class")?,
            belief_road: r.uint("belief_road")?,
            used_arte: r.uint("used_arte")?,
            safe_state: r.uint("safe_state")?,
            v_valid: r.uint("v_valid")?,
            // absent in logs written before it existed: 0 (see the field)
            roads_taken: match r.v.get("roads_taken") {
                None => 0,
                Some(_) => r.uint("roads_taken")?,
            },
            faults: read_faults(&r.sub("faults")?)?,
            // absent in logs written before it existed: 0 (none known)
            road_taken: match r.v.get("road_taken") {
                None => 0,
                Some(_) => r.uint("road_taken")?,
            },
        })
    }
    fn stamp_ns(&self) -> u64 {
        self.stamp_ns
    }
}

impl McapRecord for CanFrame {
    const SCHEMA_NAME: &'static str = CanFrame::TYPE_NAME;
    fn json_schema() -> Value {
        schema(
            Self::SCHEMA_NAME,
            "Classic CAN frame tcs-loop received or sent (its CAN log). Decode data with the DBC that the attached can.toml names (attached too); torque signals are N m at one driven wheel",
            &[
                (
                    "stamp_ns",
                    t_int(
                        "CLOCK_MONOTONIC ns: arrival time of a received frame (the kernel's receive time on SocketCAN, the publish time on the simulated bus; logs written before 2026-12-07 carry the time tcs-loop read it), the cycle's time of a sent one",
                    ),
                ),
                ("id", t_int("identifier (11 bit, or 29 bit with flag 1)")),
                ("dlc", t_int("data length code 0..8")),
                (
                    "direction",
                    t_int("0 = received by tcs-loop, 1 = sent by tcs-loop"),
                ),
                (
                    "bus",
                    t_int(
                        "bus number: can.toml bus_id, on received and sent frames alike (logs of grip until 2026-12-07 have 0 on sent ones)",
                    ),
                ),
                (
                    "flags",
                    t_int(
                        "bits: 1 extended id, 2 remote frame, 4 error frame, 8 rejected by tcs-loop's E2E check",
                    ),
                ),
                (
                    "data",
                    t_arr("integer", 8, "the 8 data bytes; bytes from dlc on are 0"),
                ),
            ],
        )
    }
    fn write_json(&self, out: &mut Vec<u8>) {
        let mut o = Obj::new(out);
        o.u("stamp_ns", self.stamp_ns)
            .u("id", self.id.into())
            .u("dlc", self.dlc.into())
            .u("direction", self.direction.into())
            .u("bus", self.bus.into())
            .u("flags", self.flags.into())
            .arr("data", &self.data, |b, x| {
                let _ = write!(b, "{x}");
            });
        o.end();
    }
    fn from_json(v: &Value) -> Result<Self, JsonError> {
        let r = root(v, Self::SCHEMA_NAME)?;
        let data = r.data8()?;
        Ok(CanFrame {
            stamp_ns: r.u64("stamp_ns")?,
            id: r.uint("id")?,
            dlc: r.uint("dlc")?,
            direction: r.uint("direction")?,
            bus: r.uint("bus")?,
            flags: r.uint("flags")?,
            data,
        })
    }
    fn stamp_ns(&self) -> u64 {
        self.stamp_ns
    }
}

impl McapRecord for BusFrame {
    const SCHEMA_NAME: &'static str = BusFrame::TYPE_NAME;
    fn json_schema() -> Value {
        schema(
            Self::SCHEMA_NAME,
            "A frame of the vehicle bus as the recorder read it (any sender)",
            &[
                (
                    "stamp_ns",
                    t_int("receive time, CLOCK_MONOTONIC ns (kernel's on SocketCAN)"),
                ),
                (
                    "id",
                    t_int(
                        "identifier (11 bit, or 29 bit with flag 1; the error class for an error frame)",
                    ),
                ),
                ("dlc", t_int("data length code 0..8")),
                ("bus", t_int("bus number (can.toml bus_id)")),
                (
                    "flags",
                    t_int("bits: 1 extended id, 2 remote frame, 4 error frame"),
                ),
                (
                    "data",
                    t_arr("integer", 8, "the 8 data bytes; bytes from dlc on are 0"),
                ),
            ],
        )
    }
    fn write_json(&self, out: &mut Vec<u8>) {
        let mut o = Obj::new(out);
        o.u("stamp_ns", self.stamp_ns)
            .u("id", self.id.into())
            .u("dlc", self.dlc.into())
            .u("bus", self.bus.into())
            .u("flags", self.flags.into())
            .arr("data", &self.data, |b, x| {
                let _ = write!(b, "{x}");
            });
        o.end();
    }
    fn from_json(v: &Value) -> Result<Self, JsonError> {
        let r = root(v, Self::SCHEMA_NAME)?;
        let data = r.data8()?;
        Ok(BusFrame {
            stamp_ns: r.u64("stamp_ns")?,
            id: r.uint("id")?,
            dlc: r.uint("dlc")?,
            bus: r.uint("bus")?,
            flags: r.uint("flags")?,
            _reserved: 0,
            data,
        })
    }
    fn stamp_ns(&self) -> u64 {
        self.stamp_ns
    }
}

impl McapRecord for GroundTruth {
    const SCHEMA_NAME: &'static str = GroundTruth::TYPE_NAME;
    fn json_schema() -> Value {
        schema(
            Self::SCHEMA_NAME,
            "True plant state from plant-sim (simulated drives only; the controller never sees it). Torque is N m at ONE driven wheel; road indices count in roads.toml's road list",
            &[
                (
                    "seq",
                    t_int("plant cycle number, from 0 at plant-sim's start, +1 per cycle"),
                ),
                (
                    "stamp_ns",
                    t_int("CLOCK_MONOTONIC time of the plant cycle, ns"),
                ),
                (
                    "road_index",
                    t_int(
                        "true road under the driven wheel, an index into roads.toml's road list (4294967295 = none)",
                    ),
                ),
                (
                    "mic_road_index",
                    t_int(
                        "true road at the microphone, at x + mic_lead_m, same index (4294967295 = none)",
                    ),
                ),
                (
                    "road_name",
                    t_str("name of the true road under the driven wheel"),
                ),
                (
                    "mic_road_name",
                    t_str("name of the true road at the microphone"),
                ),
                ("v", t_num("true vehicle (chassis) speed V, m/s")),
                ("omega", t_num("true driven-wheel angular speed, rad/s")),
                (
                    "lambda",
                    t_num(
                        "true slip (r omega - V) / max(abs(r omega), abs(V), v_eps), r and v_eps from the vehicle file: above 0 the wheel turns faster than the car (drive slip), below 0 slower",
                    ),
                ),
                (
                    "torque",
                    t_num(
                        "true motor torque after the motor lag, N m at one driven wheel (reported with sensor noise as MotorStatus TorqueActual)",
                    ),
                ),
                (
                    "x",
                    t_num(
                        "position along the scenario, m: 0 at the scenario start, negative in the pre-roll, frozen while plant-sim holds the car; not the origin of tcs-loop's odometer",
                    ),
                ),
            ],
        )
    }
    fn write_json(&self, out: &mut Vec<u8>) {
        let mut o = Obj::new(out);
        o.u("seq", self.seq)
            .u("stamp_ns", self.stamp_ns)
            .u("road_index", self.road_index.into())
            .u("mic_road_index", self.mic_road_index.into())
            .s("road_name", name_from_bytes(&self.road_name).unwrap_or(""))
            .s(
                "mic_road_name",
                name_from_bytes(&self.mic_road_name).unwrap_or(""),
            )
            .f("v", self.v)
            .f("omega", self.omega)
            .f("lambda", self.lambda)
            .f("torque", self.torque)
            .f("x", self.x);
        o.end();
    }
    fn from_json(v: &Value) -> Result<Self, JsonError> {
        let r = root(v, Self::SCHEMA_NAME)?;
        Ok(GroundTruth {
            seq: r.u64("seq")?,
            stamp_ns: r.u64("stamp_ns")?,
            road_index: r.uint("road_index")?,
            mic_road_index: r.uint("mic_road_index")?,
            road_name: r.name("road_name")?,
            mic_road_name: r.name("mic_road_name")?,
            v: r.f64("v")?,
            omega: r.f64("omega")?,
            lambda: r.f64("lambda")?,
            torque: r.f64("torque")?,
            x: r.f64("x")?,
        })
    }
    fn stamp_ns(&self) -> u64 {
        self.stamp_ns
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An audio block whose `n_samples` claims more than the block holds
    /// (a faulty publisher) is written as the samples it holds and reads
    /// back (it was recorded, then refused on reading as "N samples but
    /// n_samples = M").
    #[test]
    fn an_audio_block_claiming_too_many_samples_reads_back() {
        let mut a = AudioBlock::zeroed();
        a.seq = 3;
        a.sample_rate = 48_000;
        for (i, x) in a.samples.iter_mut().enumerate() {
            *x = (i % 1000) as i16;
        }
        for claimed in [AUDIO_MAX_SAMPLES as u32 + 1, u32::MAX] {
            a.n_samples = claimed;
            let mut out = Vec::new();
            a.write_json(&mut out);
            let v: Value = serde_json::from_slice(&out).unwrap();
            let b = AudioBlock::from_json(&v).unwrap_or_else(|e| panic!("{claimed}: {e}"));
            assert_eq!(b.n_samples as usize, AUDIO_MAX_SAMPLES);
            assert_eq!(b.samples(), a.samples());
        }
        // an honest count is kept as it is
        a.n_samples = 7;
        let mut out = Vec::new();
        a.write_json(&mut out);
        let b = AudioBlock::from_json(&serde_json::from_slice(&out).unwrap()).unwrap();
        assert_eq!((b.n_samples, b.samples()), (7, &a.samples[..7]));
    }

    /// What the README must hold of schema `s`, as (where, text): the
    /// record's title and description, and a `| `field` | description |`
    /// table row per field (nested objects too).
    fn wanted(s: &Value, out: &mut Vec<(String, String)>) {
        let title = s["title"].as_str().unwrap_or_default();
        out.push((title.to_owned(), title.to_owned()));
        let d = s["description"].as_str().unwrap_or_default();
        out.push((title.to_owned(), d.to_owned()));
        for (k, v) in s["properties"].as_object().into_iter().flatten() {
            let d = v["description"].as_str().unwrap_or_default();
            assert!(
                !d.contains('|'),
                "{title}.{k}: a pipe would split the README's table cell: {d}"
            );
            out.push((format!("{title}.{k}"), format!("| `{k}` | {d} |")));
            if v.get("properties").is_some() {
                wanted(v, out);
            }
        }
    }

    /// The crate README's "Reading a drive log without grip" gives every
    /// record and field in the schema's own words, so that a reader of
    /// either finds the same meaning: a description changed in one must be
    /// changed in the other.
    #[test]
    fn the_readme_describes_every_field_as_the_schema_does() {
        let readme = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/README.md"))
            .expect("crates/io/README.md");
        let mut want = Vec::new();
        for s in [
            AudioBlock::json_schema(),
            RoadEstimate::json_schema(),
            CycleRecord::json_schema(),
            CanFrame::json_schema(),
            BusFrame::json_schema(),
            GroundTruth::json_schema(),
        ] {
            wanted(&s, &mut want);
        }
        let missing: Vec<String> = want
            .iter()
            .filter(|(_, text)| !readme.contains(text.as_str()))
            .map(|(at, text)| format!("{at}: {text}"))
            .collect();
        assert!(
            missing.is_empty(),
            "crates/io/README.md lacks, word for word:\n{}",
            missing.join("\n")
        );
    }
}
