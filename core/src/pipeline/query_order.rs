//! The order TraceMap traces its shadow queries in: each pixel's samples in the renderer's
//! trace order ([`TraceOrder`]), so a segment packet's rays leave from one part of the pixel,
//! as the monolithic renderer's do. Only the tracing order changes: answers go back to their
//! queries' places.

use super::records::ShadowQuery;
use crate::sampling::TraceOrder;
use std::ops::Range;

/// Puts shadow queries in trace order, with its scratch space kept from call to call.
pub(super) struct QueryOrder {
    order: TraceOrder,
    /// Per trace position: the index in `runs` of that sample's queries, or [`EMPTY`].
    slots: Vec<u32>,
    /// The current pixel's runs of one sample's queries.
    runs: Vec<Range<usize>>,
}

/// An empty slot.
const EMPTY: u32 = u32::MAX;

impl QueryOrder {
    /// For queries of a plan with `spp` samples per pixel.
    pub(super) fn new(spp: u32) -> QueryOrder {
        QueryOrder {
            order: TraceOrder::new(spp),
            slots: vec![EMPTY; spp as usize],
            runs: Vec::new(),
        }
    }

    /// Appends to `out` the indices `0..queries.len()` in trace order: pixel by pixel as the
    /// queries come, and within a run of one pixel's queries, its runs of one sample's queries
    /// (lights together) by the sample's place in the trace order. A pixel run holding fewer
    /// than one in eight of the pixel's samples keeps its order (too few to pay for it), and so
    /// does a sample run whose sample is out of range or already placed, after the pixel's
    /// others (never the case in queries sorted by (pixel, sample, light), as Expand writes
    /// them).
    ///
    /// Guarantee: `out` gains a permutation of `0..queries.len()`, whatever the queries hold.
    pub(super) fn append(&mut self, queries: &[ShadowQuery], out: &mut Vec<usize>) {
        let spp = self.slots.len();
        let mut start = 0;
        while start < queries.len() {
            let pixel = queries[start].pixel;
            let end = run_end(queries, start..queries.len(), |q| q.pixel == pixel);
            self.runs.clear();
            let mut run_start = start;
            while run_start < end {
                let sample = queries[run_start].sample;
                let run_end = run_end(queries, run_start..end, |q| q.sample == sample);
                self.runs.push(run_start..run_end);
                run_start = run_end;
            }
            if self.runs.len() * 8 < spp {
                out.extend(start..end);
                start = end;
                continue;
            }
            let mut leftover = Vec::new();
            for (r, run) in self.runs.iter().enumerate() {
                let sample = queries[run.start].sample;
                let slot = (sample as usize)
                    .lt(&spp)
                    .then(|| self.order.position(sample))
                    .filter(|&slot| self.slots[slot] == EMPTY);
                match slot {
                    Some(slot) => self.slots[slot] = r as u32,
                    None => leftover.push(r),
                }
            }
            for slot in self.slots.iter_mut().filter(|slot| **slot != EMPTY) {
                out.extend(self.runs[*slot as usize].clone());
                *slot = EMPTY;
            }
            for r in leftover {
                out.extend(self.runs[r].clone());
            }
            start = end;
        }
    }
}

/// The end of the run of queries in `range` from its start that meet `same`.
fn run_end(
    queries: &[ShadowQuery],
    range: Range<usize>,
    same: impl Fn(&ShadowQuery) -> bool,
) -> usize {
    range.start + queries[range].iter().take_while(|q| same(q)).count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn query(pixel: u32, sample: u32, light: u32) -> ShadowQuery {
        ShadowQuery {
            pixel,
            sample,
            light,
            origin: Vec3::ZERO,
        }
    }

    fn traced(order: &mut QueryOrder, queries: &[ShadowQuery]) -> Vec<(u32, u32, u32)> {
        let mut out = vec![usize::MAX];
        order.append(queries, &mut out);
        assert_eq!(out.remove(0), usize::MAX, "appends");
        let mut sorted = out.clone();
        sorted.sort_unstable();
        assert_eq!(
            sorted,
            (0..queries.len()).collect::<Vec<_>>(),
            "a permutation"
        );
        out.iter()
            .map(|&i| (queries[i].pixel, queries[i].sample, queries[i].light))
            .collect()
    }

    /// Sorted queries come out pixel by pixel, each pixel's samples in trace order with their
    /// lights together in light order; sparse pixels keep their order.
    #[test]
    fn each_pixels_samples_in_trace_order() {
        let spp = 64u32;
        let trace = TraceOrder::new(spp);
        let mut order = QueryOrder::new(spp);
        let mut queries = Vec::new();
        // Pixel 5: every sample, two lights (sample 3 only the second).
        for sample in 0..spp {
            for light in 0..2 {
                if sample != 3 || light == 1 {
                    queries.push(query(5, sample, light));
                }
            }
        }
        // Pixel 9: two samples only (sparse).
        queries.push(query(9, 1, 0));
        queries.push(query(9, 40, 0));
        let got = traced(&mut order, &queries);
        let mut expected = Vec::new();
        for &sample in trace.samples() {
            for light in 0..2 {
                if sample != 3 || light == 1 {
                    expected.push((5, sample, light));
                }
            }
        }
        expected.extend([(9, 1, 0), (9, 40, 0)]);
        assert_eq!(got, expected);
        // The slots are left empty: the same answer again.
        assert_eq!(traced(&mut order, &queries), expected);
    }

    /// Unsorted, repeated and out-of-range samples still give a permutation: runs that cannot
    /// take a slot come after their pixel's placed runs, in their order.
    #[test]
    fn any_queries_give_a_permutation() {
        let trace = TraceOrder::new(16);
        let mut order = QueryOrder::new(16);
        let mut queries: Vec<ShadowQuery> = (0..16).map(|s| query(2, s, 0)).collect();
        queries.extend([
            query(2, 7, 1),
            query(2, 99, 0),
            query(2, 7, 0),
            query(1, 0, 0),
        ]);
        queries.extend((0..16).rev().map(|s| query(1, s, 0)));
        let got = traced(&mut order, &queries);
        let in_trace_order = |pixel| trace.samples().iter().map(move |&s| (pixel, s, 0));
        let mut expected: Vec<_> = in_trace_order(2).collect();
        expected.extend([(2, 7, 1), (2, 99, 0), (2, 7, 0)]);
        expected.extend(in_trace_order(1));
        expected.push((1, 0, 0));
        assert_eq!(got, expected);
    }
}
