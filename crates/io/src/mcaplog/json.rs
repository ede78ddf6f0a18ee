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
        "CAN receive fault counters since start",
        &[
            ("crc", t_int("bad CRC")),
            ("counter_repeated", t_int("repeated alive counter")),
            ("counter_skipped", t_int("skipped alive counter")),
            ("length", t_int("wrong DLC")),
            ("unknown_id", t_int("unknown identifier")),
            ("timeout", t_int("timeout episodes")),
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
            "Block of mono 16-bit PCM from the tyre microphone",
            &[
                ("seq", t_int("block sequence number")),
                (
                    "stamp_ns",
                    t_int("CLOCK_MONOTONIC time of the first sample, ns"),
                ),
                ("sample_rate", t_int("Hz")),
                ("n_samples", t_int("valid samples")),
                ("channel", t_int("capture channel")),
                ("xruns", t_int("capture overruns since start")),
                (
                    "samples",
                    t_arr(
                        "integer",
                        AUDIO_MAX_SAMPLES,
                        "PCM samples (n_samples of them)",
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
            .u("n_samples", self.n_samples.into())
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
            "Acoustic road-type estimate for one audio frame",
            &[
                ("seq", t_int("decision sequence number")),
                ("stamp_ns", t_int("publish time, ns")),
                ("frame_t0_ns", t_int("audio frame start, ns")),
                ("frame_t1_ns", t_int("audio frame end, ns")),
                ("class_index", t_int("winning class (4294967295 = none)")),
                ("n_classes", t_int("valid probabilities")),
                ("class_name", t_str("winning class name")),
                (
                    "probabilities",
                    t_arr("number", MAX_ROAD_CLASSES, "class probabilities"),
                ),
                ("confidence", t_num("confidence 0..1")),
                ("lambda_opt", t_num("optimal slip of the road")),
                ("mu_peak", t_num("peak friction of the road")),
                ("alpha", t_num("MTTE relaxation factor")),
                ("x_from", t_num("tcs-loop odometer at the frame start, m")),
                ("x_to", t_num("tcs-loop odometer at the frame end, m")),
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
            "One traction-control cycle",
            &[
                ("seq", t_int("cycle number")),
                ("stamp_ns", t_int("cycle deadline, ns")),
                ("wakeup_latency_ns", t_int("wake-up minus deadline, ns")),
                ("compute_ns", t_int("wake-up to command sent, ns")),
                ("deadline_misses", t_int("deadline misses since start")),
                ("omega", t_num("measured wheel speed, rad/s")),
                ("v", t_num("measured vehicle speed, m/s")),
                ("torque", t_num("measured motor torque, N m")),
                ("demand", t_num("driver demand, N m")),
                ("torque_cmd", t_num("torque command, N m")),
                ("internal", t_num("controller internal variable")),
                ("mu_hat", t_num("friction estimate")),
                ("odometer", t_num("integral of the measured speed, m")),
                ("torque_cap", t_num("road knowledge's torque cap, N m")),
                ("belief_prob", t_num("probability of the believed road")),
                ("road_class", t_int("road class used (4294967295 = none)")),
                ("belief_road", t_int("believed road (4294967295 = none)")),
                ("used_arte", t_int("1 = ARTE knowledge used")),
                ("safe_state", t_int("1 = safe state")),
                ("v_valid", t_int("1 = v valid")),
                ("faults", faults_schema()),
                (
                    "road_taken",
                    t_int(
                        "1 + low 32 bits of the seq of the newest road estimate taken this cycle, 0 = none",
                    ),
                ),
                (
                    "roads_taken",
                    t_int("road estimates taken this cycle (absent in older logs)"),
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
            "Classic CAN frame",
            &[
                ("stamp_ns", t_int("send/receive time, ns")),
                ("id", t_int("identifier")),
                ("dlc", t_int("data length code")),
                ("direction", t_int("0 = received, 1 = sent")),
                ("bus", t_int("bus number")),
                ("flags", t_int("1 extended, 2 RTR, 4 error, 8 E2E rejected")),
                ("data", t_arr("integer", 8, "8 data bytes")),
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
                ("id", t_int("identifier (error class for an error frame)")),
                ("dlc", t_int("data length code")),
                ("bus", t_int("bus number")),
                ("flags", t_int("1 extended, 2 RTR, 4 error")),
                ("data", t_arr("integer", 8, "8 data bytes")),
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
            "True plant state from the simulator",
            &[
                ("seq", t_int("plant step")),
                ("stamp_ns", t_int("time, ns")),
                (
                    "road_index",
                    t_int("true road under the driven wheel (4294967295 = none)"),
                ),
                (
                    "mic_road_index",
                    t_int("true road at the microphone (4294967295 = none)"),
                ),
                ("road_name", t_str("true road name under the driven wheel")),
                ("mic_road_name", t_str("true road name at the microphone")),
                ("v", t_num("vehicle speed, m/s")),
                ("omega", t_num("wheel speed, rad/s")),
                ("lambda", t_num("slip")),
                ("torque", t_num("motor torque, N m")),
                ("x", t_num("distance, m")),
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
