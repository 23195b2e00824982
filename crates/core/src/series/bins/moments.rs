//! A bin's exact integer moments and the two weighted Gauss nodes they become.
//!
//! Separate because it is the arithmetic that makes binning exact (the module doc of
//! `series::bins` says why), independent of how readings are routed to bins.

use super::{MAX_ABS_COUNTS, NS_PER_US};
use crate::campaign::TimeNs;

/// Integer moments of one bin's readings: sums over its samples of powers of `u` (µs since the
/// bin's start) and of the counts `c`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct BinMoments {
    pub(crate) n: u64,
    /// First and last reading, µs since the bin's start.
    pub(crate) first_us: i64,
    pub(crate) last_us: i64,
    /// Smallest and largest counts of the bin: a jump or a counter wrap inside a bin shows as
    /// a spread far beyond the noise (`series::quality`).
    pub(crate) min_counts: i64,
    pub(crate) max_counts: i64,
    pub(crate) su: i128,
    pub(crate) suu: i128,
    pub(crate) suuu: i128,
    pub(crate) sc: i128,
    pub(crate) suc: i128,
    pub(crate) scc: i128,
}

/// The products one reading adds to its bin's sums: `u²`, `u³`, `u·c`, `c²` (`u` µs since the
/// bin's start, `c` counts).
struct Products {
    uu: i128,
    uuu: i128,
    uc: i128,
    cc: i128,
}

impl Products {
    /// Every accepted reading has `0 <= u < 2³²` (a bin is at most an hour, 3.6e9 µs) and
    /// `|c| <= 2⁴⁸` ([`MAX_ABS_COUNTS`]), so `u² < 2⁶⁴`, `u³ < 2⁹⁶`, `|u·c| < 2⁸¹`, `c² <= 2⁹⁶`:
    /// no product can wrap, and each is one 64×64→128 multiplication. Spelled `wrapping_mul`
    /// so that the overflow checks our crates build with are not paid on products that cannot
    /// overflow (ingest computes them for every reading; the change measured no difference in
    /// ingest's time, within this VM's noise); the bounds are checked where readings enter
    /// ([`BinAccumulator::add_all`]) and again here in debug builds.
    #[inline]
    fn of(u: i64, c: i64) -> Self {
        let (uu, uuu) = Self::time_powers(u);
        let (uc, cc) = Self::count_products(u, c);
        Products { uu, uuu, uc, cc }
    }

    /// `u²` and `u³` (the bounds of [`Products::of`]).
    #[inline]
    fn time_powers(u: i64) -> (i128, i128) {
        debug_assert!((0..1 << 32).contains(&u));
        let uu = (u as u64 as u128).wrapping_mul(u as u64 as u128) as i128;
        (uu, uu.wrapping_mul(u as i128))
    }

    /// `u·c` and `c²` (the bounds of [`Products::of`]).
    #[inline]
    fn count_products(u: i64, c: i64) -> (i128, i128) {
        debug_assert!(c.unsigned_abs() <= MAX_ABS_COUNTS as u64);
        (
            (u as i128).wrapping_mul(c as i128),
            (c as i128).wrapping_mul(c as i128),
        )
    }
}

/// One node of a compressed bin: a weighted pseudo-reading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Node {
    /// Time since the bin's start, µs.
    pub(crate) offset_us: f64,
    /// Number of readings the node stands for (the two weights of a bin sum to its `n`).
    pub(crate) weight: f64,
    /// The bin's least-squares line at the node, counts.
    pub(crate) counts: f64,
}

impl BinMoments {
    /// Add readings of this bin (times in ns, the bin starting at `start_ns`).
    ///
    /// Ingest adds every reading of a campaign here, so the loop is kept lean: two passes, the
    /// times' sums and then the counts' (one loop of twelve 64-bit halves of sums and four
    /// extremes spills registers on every row); the times' sums in unsigned arithmetic (`u` is
    /// never negative: `u²` is one 64-bit product, `u³` one 64×64→128); and wrapping additions
    /// for the reason [`Products::of`] gives: no sum can wrap for accepted readings (at most
    /// `MAX_BAR_READINGS` = 2³¹ a bar: `Σ u < 2⁶³`, `Σ u³ < 2¹²⁷`), where the overflow checks
    /// our crates build with would be six 128-bit checked additions a reading.
    pub(crate) fn add_run(&mut self, start_ns: TimeNs, time_ns: &[TimeNs], counts: &[i64]) {
        let n = time_ns.len().min(counts.len());
        let (time_ns, counts) = (&time_ns[..n], &counts[..n]);
        // A reading of the bin is at or after its start (both accepted times: no wrap).
        let us = |t: TimeNs| t.wrapping_sub(start_ns) as u64 / NS_PER_US as u64;
        let mut run = BinMoments {
            n: n as u64,
            ..BinMoments::default()
        };
        let (mut first, mut last) = (u64::MAX, 0);
        let (mut su, mut suu, mut suuu) = (0u64, 0u128, 0u128);
        for &t in time_ns {
            let u = us(t);
            first = first.min(u);
            last = last.max(u);
            debug_assert!(u < 1 << 32);
            let uu = u.wrapping_mul(u);
            su = su.wrapping_add(u);
            suu = suu.wrapping_add(uu as u128);
            suuu = suuu.wrapping_add((uu as u128).wrapping_mul(u as u128));
        }
        (run.first_us, run.last_us) = (first as i64, last as i64);
        (run.su, run.suu, run.suuu) = (su as i128, suu as i128, suuu as i128);
        let (mut low, mut high) = (i64::MAX, i64::MIN);
        for (&t, &c) in time_ns.iter().zip(counts) {
            low = low.min(c);
            high = high.max(c);
            let (uc, cc) = Products::count_products(us(t) as i64, c);
            run.sc = run.sc.wrapping_add(c as i128);
            run.suc = run.suc.wrapping_add(uc);
            run.scc = run.scc.wrapping_add(cc);
        }
        (run.min_counts, run.max_counts) = (low, high);
        self.merge(&run);
    }

    /// Adds one reading's powers and products to the sums (wrapping: see
    /// [`BinMoments::add_run`]).
    #[inline]
    fn add_products(&mut self, u: i64, c: i64) {
        let p = Products::of(u, c);
        self.su = self.su.wrapping_add(u as i128);
        self.suu = self.suu.wrapping_add(p.uu);
        self.suuu = self.suuu.wrapping_add(p.uuu);
        self.sc = self.sc.wrapping_add(c as i128);
        self.suc = self.suc.wrapping_add(p.uc);
        self.scc = self.scc.wrapping_add(p.cc);
    }

    /// Add one reading of this bin: [`BinMoments::add_run`] of one row, without a second sum
    /// to merge.
    #[inline]
    pub(crate) fn add_one(&mut self, start_ns: TimeNs, t: TimeNs, c: i64) {
        let u = (t - start_ns) / NS_PER_US;
        if self.n == 0 {
            (self.first_us, self.last_us) = (u, u);
            (self.min_counts, self.max_counts) = (c, c);
        } else {
            self.first_us = self.first_us.min(u);
            self.last_us = self.last_us.max(u);
            self.min_counts = self.min_counts.min(c);
            self.max_counts = self.max_counts.max(c);
        }
        self.n += 1;
        self.add_products(u, c);
    }

    /// Take back one reading added with [`BinMoments::add_one`] or [`BinMoments::add_run`]:
    /// the sums are integers, so this is exact. The first/last time and the smallest/largest
    /// counts cannot be taken back in general; they stay as they were, which is exact when the
    /// reading removed is a copy of one that stays (a duplicate row), and a bin left empty
    /// becomes the empty bin. Returns `false` (and changes nothing) on an empty bin.
    #[inline]
    pub(crate) fn remove_one(&mut self, start_ns: TimeNs, t: TimeNs, c: i64) -> bool {
        if self.n == 0 {
            return false;
        }
        if self.n == 1 {
            *self = BinMoments::default();
            return true;
        }
        let u = (t - start_ns) / NS_PER_US;
        let p = Products::of(u, c);
        self.n -= 1;
        self.su -= u as i128;
        self.suu -= p.uu;
        self.suuu -= p.uuu;
        self.sc -= c as i128;
        self.suc -= p.uc;
        self.scc -= p.cc;
        true
    }

    /// Sums of two parts of one bin.
    pub(crate) fn merge(&mut self, other: &BinMoments) {
        if other.n == 0 {
            return;
        }
        if self.n == 0 {
            (self.first_us, self.last_us) = (other.first_us, other.last_us);
            (self.min_counts, self.max_counts) = (other.min_counts, other.max_counts);
        }
        self.first_us = self.first_us.min(other.first_us);
        self.last_us = self.last_us.max(other.last_us);
        self.min_counts = self.min_counts.min(other.min_counts);
        self.max_counts = self.max_counts.max(other.max_counts);
        // Parts of one bar's readings: the sums stay within the bounds of `add_run`.
        self.n += other.n;
        self.su = self.su.wrapping_add(other.su);
        self.suu = self.suu.wrapping_add(other.suu);
        self.suuu = self.suuu.wrapping_add(other.suuu);
        self.sc = self.sc.wrapping_add(other.sc);
        self.suc = self.suc.wrapping_add(other.suc);
        self.scc = self.scc.wrapping_add(other.scc);
    }

    /// The bin's nodes (two; one when its readings share one time) and the scatter of its counts
    /// about its least-squares line, counts².
    pub(crate) fn nodes(&self) -> (Vec<Node>, f64) {
        if self.n == 0 {
            return (Vec::new(), 0.0);
        }
        let n = self.n as i128;
        // n² × centred second moments, exact.
        let nuu = n * self.suu - self.su * self.su;
        let nuc = n * self.suc - self.su * self.sc;
        let ncc = n * self.scc - self.sc * self.sc;
        let nf = self.n as f64;
        let mean_u = self.su as f64 / nf;
        let mean_c = self.sc as f64 / nf;
        if nuu <= 0 {
            let node = Node {
                offset_us: mean_u,
                weight: nf,
                counts: mean_c,
            };
            return (vec![node], (ncc as f64 / nf).max(0.0));
        }
        let slope = nuc as f64 / nuu as f64;
        let line_rss = ((ncc as f64 - (nuc as f64) * slope) / nf).max(0.0);
        // Centred moments of the sample times; x = u - mean_u.
        let m2 = nuu as f64 / (nf * nf);
        let m3 = (self.suuu as f64 - 3.0 * mean_u * self.suu as f64) / nf
            + 2.0 * mean_u * mean_u * mean_u;
        // Nodes: roots of the degree-2 orthogonal polynomial x² - (m3/m2) x - m2.
        let a = m3 / m2;
        let root = (a * a + 4.0 * m2).sqrt();
        let (x1, x2) = ((a - root) / 2.0, (a + root) / 2.0);
        let (w1, w2) = (nf * x2 / (x2 - x1), -nf * x1 / (x2 - x1));
        let node = |x: f64, w: f64| Node {
            offset_us: mean_u + x,
            weight: w,
            counts: mean_c + slope * x,
        };
        (vec![node(x1, w1), node(x2, w2)], line_rss)
    }
}
