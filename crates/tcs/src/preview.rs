//! The road ahead: a fixed-capacity, allocation-free queue of road
//! knowledge tied to places on the path.
//!
//! A microphone `lead` metres ahead of the driven wheel hears the road the
//! wheel will reach after `lead` metres. Every acoustic decision covers one
//! analysis frame, i.e. a stretch of path `[x_from, x_to]` in the *wheel's*
//! path coordinate (the loop's odometer at the frame's start and end, plus
//! the lead). When a decision names another road than the last one queued,
//! the new road is queued as beginning at
//!
//! - `x_from` when it carries less than the road before it (cautious: the
//!   change lies somewhere in the frame, so assume its earliest point), or
//! - the middle of the stretch when it carries more (the decision goes to
//!   the new road once about half its frame is on it).
//!
//! The queue places what it is given: [`crate::RoadAware::decision`] hands it
//! a frame from its `change_at` point on (`[preview] change_at` of the frame
//! from its start), so a lower-friction road begins at `change_at` of the
//! frame and a grippier one at `(1 + change_at) / 2` of it (0.6875 as
//! shipped).
//!
//! Decisions for the road already last in the queue refresh its confidence.
//! [`PreviewQueue::view`] at the wheel's odometer `x` gives the road under
//! the wheel (the last entry that begins at or before `x`) and the next one
//! ahead with its distance. Entries the wheel has passed are dropped.
//!
//! **A full queue** (a decision stream that flickers faster than the
//! capacity covers, e.g. 32 changes within the 2.77 m lead) makes room
//! among the farthest entries, never at the road under the wheel: the two
//! farthest queued entries become one, beginning where the nearer of them
//! began and naming the road that carries less (by μ_peak; a road the
//! catalogue does not know, which caps nothing, gives way to one it knows),
//! with the higher of their decision counts and peak confidences. Over their joint span the merged entry therefore
//! caps wherever either of them would have, and never above what either
//! would have: it may cap a stretch the grippier road would have left free
//! (traction given up), never the other way round (slip). The span lies
//! ahead of the wheel (as of the last `view`), and the decision being
//! queued keeps its own entry. Merges are counted in
//! [`PreviewQueue::overflows`]; after one, two neighbouring entries may
//! name the same road.
//!
//! With `lead = 0` the road under the wheel is simply the latest decision
//! (what the paper's set-up gives); nothing is ever ahead.
//!
//! Positions are `f64` metres from the start of the drive: at 1 mm
//! resolution f64 is exact far beyond any drive (2^53 mm ≈ 9·10^12 m), so
//! the queue needs no wrap handling.

/// Entries the queue holds (the road under the wheel and those ahead).
pub const PREVIEW_CAPACITY: usize = 32;

// A full queue merges its two farthest entries; the one under the wheel
// (the first, after `view`) must not be one of them.
const _: () = assert!(PREVIEW_CAPACITY >= 3);

/// One stretch of road: where it begins and what was heard.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RoadAhead {
    /// Catalogue index of the road.
    pub road: usize,
    /// Wheel path position where it begins, m.
    pub x_start: f64,
    /// Where it has surely begun, m: the end of the first frame that named
    /// it (the change lies somewhere in that frame).
    pub x_sure: f64,
    /// Confidence of the latest decision for it, [0, 1].
    pub confidence: f64,
    /// Time of the latest decision for it, s (its frame's end).
    pub stamp: f64,
    /// Decisions that named it in a row (a single stray decision between
    /// two of them does not break the row, [`PreviewQueue::push`]).
    pub hits: u32,
    /// The highest confidence any of them had (a road once heard
    /// confidently stays known while the frames straddling a change, whose
    /// calibrated confidence is honestly lower, come in).
    pub peak_confidence: f64,
}

/// What [`PreviewQueue::view`] returns.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PreviewView {
    /// The road under the wheel (`None` before the first decision has been
    /// reached).
    pub here: Option<RoadAhead>,
    /// The next road ahead and its distance from the wheel, m (> 0).
    pub next: Option<(RoadAhead, f64)>,
}

/// See the module docs.
#[derive(Debug, Clone)]
pub struct PreviewQueue {
    buf: [RoadAhead; PREVIEW_CAPACITY],
    len: usize,
    overflows: u64,
}

const EMPTY: RoadAhead = RoadAhead {
    road: usize::MAX,
    x_start: f64::NEG_INFINITY,
    x_sure: f64::NEG_INFINITY,
    confidence: 0.0,
    stamp: f64::NEG_INFINITY,
    hits: 0,
    peak_confidence: 0.0,
};

impl Default for PreviewQueue {
    fn default() -> Self {
        Self::new()
    }
}

impl PreviewQueue {
    /// An empty queue.
    pub fn new() -> Self {
        Self {
            buf: [EMPTY; PREVIEW_CAPACITY],
            len: 0,
            overflows: 0,
        }
    }

    /// Forget everything (start of a drive, or reverse travel: see
    /// [`crate::RoadAware::step`]).
    pub fn clear(&mut self) {
        self.len = 0;
        self.overflows = 0;
    }

    /// Entries held.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when nothing is queued.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Merges of the two farthest entries because the queue was full (see
    /// the module docs).
    pub fn overflows(&self) -> u64 {
        self.overflows
    }

    /// The entries, ordered by `x_start`.
    pub fn entries(&self) -> &[RoadAhead] {
        &self.buf[..self.len]
    }

    /// A decision for `road` with `confidence` at time `stamp`, heard over
    /// the wheel-path stretch `[x_from, x_to]` (m; `x_from <= x_to`).
    /// `mu_peak(i)` is road `i`'s peak friction (NaN, for a road not known,
    /// counts as carrying less than any: the cautious reading). A road that carries
    /// less than the last queued one begins at the stretch's start, a
    /// grippier one at its middle; non-finite positions are ignored.
    /// Allocation-free.
    ///
    /// A classifier mishears some frames: a lower-friction road begins where
    /// the run of unconfirmed (one-decision) grippier entries just before it
    /// begins (a mixed frame at the change may have been this road misheard;
    /// placing it late is the dangerous direction). And one stray decision
    /// between two for the same road (two of three) goes, so that it neither
    /// hides the road nor breaks its confirmation; a stray never confirmed
    /// never capped anything.
    pub fn push(
        &mut self,
        road: usize,
        confidence: f64,
        stamp: f64,
        x_from: f64,
        x_to: f64,
        mu_peak: impl Fn(usize) -> f64,
    ) {
        if !(x_from.is_finite() && x_to.is_finite()) {
            return;
        }
        let (lo, hi) = if x_from <= x_to {
            (x_from, x_to)
        } else {
            (x_to, x_from)
        };
        let mu = mu_peak;
        let m = mu(road);
        // Does `road` carry less than road `other`? (unknown: yes)
        let less = |other: usize| {
            let o = mu(other);
            m < o || m.is_nan() || o.is_nan()
        };
        let carries_less = self.entries().last().is_none_or(|e| less(e.road));
        let mut earliest = f64::INFINITY;
        if carries_less {
            while let Some(last) = self.entries().last()
                && last.hits == 1
                && less(last.road)
            {
                earliest = earliest.min(last.x_start);
                self.len -= 1;
            }
        }
        // One stray decision between two for the same road (two of three).
        if self.len >= 2
            && self.buf[self.len - 1].hits == 1
            && self.buf[self.len - 1].road != road
            && self.buf[self.len - 2].road == road
        {
            self.len -= 1;
        }
        if let Some(last) = self.buf[..self.len].last_mut()
            && last.road == road
        {
            last.confidence = confidence;
            last.stamp = stamp;
            last.hits = last.hits.saturating_add(1);
            last.peak_confidence = last.peak_confidence.max(confidence);
            return;
        }
        let mut x_start = if carries_less {
            lo.min(earliest)
        } else {
            0.5 * (lo + hi)
        };
        // Keep the queue ordered: a road cannot begin before one heard earlier.
        // A cautious (earlier) start moves the previous entries that now lie
        // behind it out of the way: they are replaced by this road.
        while self.len > 0 && self.buf[self.len - 1].x_start >= x_start {
            if carries_less {
                self.len -= 1;
            } else {
                x_start = self.buf[self.len - 1].x_start;
                break;
            }
        }
        if self.len > 0 && self.buf[self.len - 1].x_start >= x_start {
            // Same start as a (grippier) entry: this decision replaces it.
            self.len -= 1;
        }
        if self.len == PREVIEW_CAPACITY {
            // Full: the two farthest entries become one (module docs); the
            // road under the wheel, the first entry, is never touched.
            let (near, far) = (self.buf[self.len - 2], self.buf[self.len - 1]);
            // A road not known (NaN) caps nothing: a known one is kept.
            let (m_near, m_far) = (mu(near.road), mu(far.road));
            let keep = if m_far < m_near || (m_near.is_nan() && !m_far.is_nan()) {
                far
            } else {
                near
            };
            self.buf[self.len - 2] = RoadAhead {
                x_start: near.x_start,
                hits: near.hits.max(far.hits),
                peak_confidence: near.peak_confidence.max(far.peak_confidence),
                ..keep
            };
            self.len -= 1;
            self.overflows += 1;
        }
        self.buf[self.len] = RoadAhead {
            road,
            x_start,
            x_sure: hi.max(x_start),
            confidence,
            stamp,
            hits: 1,
            peak_confidence: confidence,
        };
        self.len += 1;
    }

    /// The road under the wheel at odometer `x` and the next one ahead;
    /// drops entries the wheel has left behind. Allocation-free.
    pub fn view(&mut self, x: f64) -> PreviewView {
        // Index of the last entry beginning at or before x.
        let here = self.buf[..self.len].iter().rposition(|e| e.x_start <= x);
        if let Some(i) = here
            && i > 0
        {
            self.buf.copy_within(i..self.len, 0);
            self.len -= i;
        }
        let (here, first_ahead) = match here {
            Some(_) => (Some(self.buf[0]), 1),
            None => (None, 0),
        };
        let next = (first_ahead < self.len).then(|| {
            let e = self.buf[first_ahead];
            (e, e.x_start - x)
        });
        PreviewView { here, next }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// μ_peak of the test roads: 0 asphalt, 1 gravel-like, 2 snow, 3 grippier than asphalt.
    const MU: [f64; 4] = [1.0, 0.5, 0.2, 1.1];

    fn mu(i: usize) -> f64 {
        MU.get(i).copied().unwrap_or(f64::NAN)
    }

    #[test]
    fn lead_zero_gives_the_latest_decision() {
        let mut q = PreviewQueue::new();
        assert_eq!(q.view(0.0), PreviewView::default());
        q.push(0, 0.9, 0.1, 0.0, 0.5, mu);
        // grippier-or-equal start at the frame's middle
        let v = q.view(0.25);
        assert_eq!(v.here.unwrap().road, 0);
        assert!(v.next.is_none());
        q.push(2, 0.8, 0.2, 0.5, 1.0, mu); // snow: begins at the frame start
        let v = q.view(1.0);
        assert_eq!(v.here.unwrap().road, 2);
        assert!(v.next.is_none());
        assert_eq!(q.len(), 1, "passed entries are dropped");
    }

    #[test]
    fn ordering_and_distance_ahead() {
        let mut q = PreviewQueue::new();
        let lead = 2.77;
        q.push(0, 0.9, 0.1, 0.0 + lead, 0.3 + lead, mu);
        q.push(0, 0.95, 0.125, 0.1 + lead, 0.4 + lead, mu);
        assert_eq!(q.len(), 1, "same road refreshes");
        assert_eq!(q.entries()[0].confidence, 0.95);
        assert_eq!(q.entries()[0].hits, 2);
        q.push(2, 0.8, 0.2, 1.0 + lead, 1.3 + lead, mu);
        q.push(1, 0.7, 0.3, 2.0 + lead, 2.3 + lead, mu);
        let v = q.view(1.0);
        assert!(v.here.is_none(), "nothing has reached the wheel yet");
        let (n, d) = v.next.unwrap();
        assert_eq!(n.road, 0);
        assert!(
            (d - (lead - 1.0)).abs() < 1e-12,
            "the first road from its frame's start: {d}"
        );
        let v = q.view(3.9);
        assert_eq!(v.here.unwrap().road, 2);
        let (n, d) = v.next.unwrap();
        assert_eq!(n.road, 1);
        assert!((d - (2.15 + lead - 3.9)).abs() < 1e-12, "{d}");
    }

    #[test]
    fn change_exactly_at_a_cycle_boundary() {
        let mut q = PreviewQueue::new();
        q.push(0, 0.9, 0.0, 0.0, 0.0, mu);
        q.push(0, 0.9, 0.0, 0.0, 0.0, mu);
        q.push(2, 0.9, 0.1, 5.0, 5.5, mu);
        // At x = 5.0 exactly the wheel is on the new road.
        assert_eq!(q.view(4.999_999).here.unwrap().road, 0);
        assert_eq!(q.view(5.0).here.unwrap().road, 2);
    }

    #[test]
    fn cautious_start_replaces_entries_behind_it() {
        let mut q = PreviewQueue::new();
        q.push(0, 0.9, 0.0, 0.0, 1.0, mu); // the first road: from 0.0
        q.push(0, 0.9, 0.0, 0.5, 1.5, mu); // confirmed
        q.push(3, 0.9, 0.1, 1.5, 2.5, mu); // grippier stone starts at 2.0
        q.push(3, 0.9, 0.1, 2.0, 3.0, mu); // confirmed
        q.push(2, 0.9, 0.2, 1.8, 2.3, mu); // snow may start at 1.8: before stone
        let e = q.entries();
        assert_eq!(e.len(), 2);
        assert_eq!((e[0].road, e[0].x_start), (0, 0.0));
        assert_eq!((e[1].road, e[1].x_start), (2, 1.8));
    }

    #[test]
    fn capacity_is_fixed_and_overflow_counted() {
        let mut q = PreviewQueue::new();
        for i in 0..(PREVIEW_CAPACITY + 5) {
            // Each road heard twice (confirmed), alternating.
            let x = i as f64;
            q.push(i % 2, 0.9, x, x, x + 0.5, mu);
            q.push(i % 2, 0.9, x + 0.5, x + 0.5, x + 1.0, mu);
        }
        assert_eq!(q.len(), PREVIEW_CAPACITY);
        assert_eq!(q.overflows(), 5);
        let e = q.entries();
        assert!(e.windows(2).all(|w| w[0].x_start < w[1].x_start));
    }

    /// Queue `road` twice (confirmed) over two frames of `frame` m from `x`.
    fn confirmed(q: &mut PreviewQueue, road: usize, x: f64, frame: f64) {
        q.push(road, 0.9, x, x, x + frame, mu);
        q.push(road, 0.9, x + frame, x + frame, x + 2.0 * frame, mu);
    }

    #[test]
    fn a_full_queue_keeps_the_road_under_the_wheel() {
        // The wheel is on snow; ahead a classifier flickers between asphalt
        // and gravel in confirmed pairs, 4 cm frames (1.6 m/s at a 25 ms
        // hop), far more changes than the queue holds within the lead.
        let mut q = PreviewQueue::new();
        confirmed(&mut q, 2, 0.0, 0.5);
        let x = 1.0;
        assert_eq!(q.view(x).here.unwrap().road, 2);
        for i in 0..(2 * PREVIEW_CAPACITY) {
            confirmed(&mut q, i % 2, 1.5 + 0.08 * i as f64, 0.04);
            let v = q.view(x);
            let here = v.here.unwrap_or_else(|| panic!("lost after {i}: {q:?}"));
            assert_eq!((here.road, here.x_start), (2, 0.0), "after {i}");
        }
        assert!(q.overflows() > 0, "the queue never filled");
        assert_eq!(q.len(), PREVIEW_CAPACITY);
        let e = q.entries();
        assert!(e.windows(2).all(|w| w[0].x_start < w[1].x_start));
        // Under the wheel the road still caps: confirmed, confident snow.
        assert_eq!((e[0].road, e[0].hits, e[0].peak_confidence), (2, 2, 0.9));
    }

    /// A full queue whose last two entries are `near` then `far` (both
    /// first heard at `x_near`, `x_far`), ahead of snow under the wheel.
    fn full_with(near: (usize, u32, f64), far: (usize, u32, f64)) -> PreviewQueue {
        let mut q = PreviewQueue::new();
        confirmed(&mut q, 2, 0.0, 0.5);
        let mut x = 2.0;
        // Alternating asphalt and stone (both grippier than gravel and
        // snow), confirmed, up to two short of full.
        while q.len() < PREVIEW_CAPACITY - 2 {
            let road = if q.len().is_multiple_of(2) { 0 } else { 3 };
            confirmed(&mut q, road, x, 0.1);
            x += 1.0;
        }
        for (road, hits, conf) in [near, far] {
            for h in 0..hits {
                let x0 = x + 0.1 * h as f64;
                q.push(road, conf, x0, x0, x0 + 0.1, mu);
            }
            x += 1.0;
        }
        assert_eq!(q.len(), PREVIEW_CAPACITY, "{q:?}");
        q
    }

    #[test]
    fn the_merged_farthest_span_carries_the_lower_friction_road() {
        let lead = |q: &PreviewQueue, i: usize| q.entries()[PREVIEW_CAPACITY - 2 + i];
        // Gravel near, asphalt far: gravel is kept and carries on over
        // asphalt's stretch. A stone decision beyond keeps its own entry.
        let mut q = full_with((1, 2, 0.8), (0, 3, 0.9));
        let (near, far) = (lead(&q, 0), lead(&q, 1));
        q.push(3, 0.7, 99.0, 99.0, 99.1, mu);
        assert_eq!(q.overflows(), 1);
        assert_eq!(q.len(), PREVIEW_CAPACITY);
        let m = q.entries()[PREVIEW_CAPACITY - 2];
        assert_eq!(
            (m.road, m.x_start, m.x_sure),
            (1, near.x_start, near.x_sure)
        );
        assert_eq!((m.hits, m.peak_confidence), (3, 0.9));
        let last = q.entries()[PREVIEW_CAPACITY - 1];
        assert_eq!((last.road, last.hits), (3, 1));
        assert!(far.x_start < last.x_start);
        // Asphalt near, snow far: snow is kept and begins where asphalt
        // began (earlier: the cautious direction), with the stronger
        // confirmation of the two (the snow was heard once only).
        let mut q = full_with((0, 2, 0.9), (2, 1, 0.95));
        let (near, far) = (lead(&q, 0), lead(&q, 1));
        q.push(1, 0.8, 99.0, 99.0, 99.1, mu);
        let m = q.entries()[PREVIEW_CAPACITY - 2];
        assert_eq!((m.road, m.x_start), (2, near.x_start));
        assert_eq!(
            (m.x_sure, m.confidence, m.stamp),
            (far.x_sure, 0.95, far.stamp)
        );
        assert_eq!((m.hits, m.peak_confidence), (2, 0.95));
        // A road the catalogue does not know caps nothing: the known one
        // stays (gravel unknown to this decision's table).
        let mut q = full_with((1, 2, 0.9), (2, 2, 0.9));
        q.push(0, 0.8, 99.0, 99.0, 99.1, |i| {
            if i == 1 { f64::NAN } else { mu(i) }
        });
        let m = q.entries()[PREVIEW_CAPACITY - 2];
        assert_eq!(m.road, 2);
        // Nothing before the two farthest moved, the road under the wheel
        // least of all.
        let before = full_with((0, 2, 0.9), (1, 2, 0.9));
        let mut after = before.clone();
        after.push(3, 0.8, 99.0, 99.0, 99.1, mu);
        assert_eq!(
            before.entries()[..PREVIEW_CAPACITY - 2],
            after.entries()[..PREVIEW_CAPACITY - 2]
        );
    }

    #[test]
    fn long_drive_positions_stay_exact() {
        // 1000 km of 1 mm steps is far inside f64's exact range; the queue
        // compares positions only, so a long drive behaves like a short one.
        let mut q = PreviewQueue::new();
        let x0 = 1.0e6;
        q.push(0, 0.9, 0.0, x0, x0, mu);
        q.push(0, 0.9, 0.0, x0, x0, mu);
        q.push(2, 0.9, 0.1, x0 + 0.001, x0 + 0.002, mu);
        assert_eq!(q.view(x0 + 0.000_999).here.unwrap().road, 0);
        assert_eq!(q.view(x0 + 0.001).here.unwrap().road, 2);
    }

    #[test]
    fn a_stray_decision_between_two_for_the_same_road_goes() {
        let mut q = PreviewQueue::new();
        q.push(2, 0.9, 0.1, 1.0, 1.5, mu); // snow
        q.push(3, 0.9, 0.2, 1.5, 2.0, mu); // one frame heard as stone
        q.push(2, 0.9, 0.3, 2.0, 2.5, mu); // snow again
        let e = q.entries();
        assert_eq!(e.len(), 1, "{e:?}");
        assert_eq!((e[0].road, e[0].x_start, e[0].hits), (2, 1.0, 2));
        // Two strays in a row are not strays: stone stays.
        q.push(3, 0.9, 0.4, 2.5, 3.0, mu);
        q.push(3, 0.9, 0.5, 3.0, 3.5, mu);
        q.push(2, 0.9, 0.6, 3.5, 4.0, mu);
        let roads: Vec<usize> = q.entries().iter().map(|e| e.road).collect();
        assert_eq!(roads, [2, 3, 2]);
    }

    #[test]
    fn a_lower_friction_road_begins_where_unconfirmed_frames_before_it_begin() {
        let mut q = PreviewQueue::new();
        q.push(0, 0.9, 0.1, 0.0, 0.5, mu); // asphalt
        q.push(0, 0.9, 0.2, 0.5, 1.0, mu);
        q.push(1, 0.6, 0.3, 1.0, 1.5, mu); // a mixed frame, heard as gravel
        q.push(2, 0.9, 0.4, 1.5, 2.0, mu); // snow
        let e = q.entries();
        assert_eq!(e.len(), 2, "{e:?}");
        assert_eq!(
            (e[1].road, e[1].x_start),
            (2, 1.0),
            "from the gravel frame's start"
        );
        // A confirmed grippier road is not taken back.
        let mut q = PreviewQueue::new();
        q.push(0, 0.9, 0.0, -0.5, 0.0, mu);
        q.push(0, 0.9, 0.1, 0.0, 0.5, mu);
        q.push(1, 0.9, 0.2, 0.5, 1.0, mu);
        q.push(1, 0.9, 0.3, 1.0, 1.5, mu);
        q.push(2, 0.9, 0.4, 1.5, 2.0, mu);
        let e = q.entries();
        assert_eq!((e[2].road, e[2].x_start), (2, 1.5));
        // Nor an unconfirmed road that carries even less (ice-like, road 2
        // before gravel-like 1): it stays ahead of the gravel.
        let mut q = PreviewQueue::new();
        q.push(0, 0.9, 0.0, -0.5, 0.0, mu);
        q.push(0, 0.9, 0.1, 0.0, 0.5, mu);
        q.push(2, 0.9, 0.2, 0.5, 1.0, mu);
        q.push(1, 0.9, 0.3, 1.0, 1.5, mu);
        let roads: Vec<usize> = q.entries().iter().map(|e| e.road).collect();
        assert_eq!(roads, [0, 2, 1]);
    }

    #[test]
    fn non_finite_positions_are_ignored() {
        let mut q = PreviewQueue::new();
        q.push(0, 0.9, 0.0, f64::NAN, 1.0, mu);
        assert!(q.is_empty());
    }
}
