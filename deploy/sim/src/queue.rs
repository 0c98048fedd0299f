//! The virtual-time event queue: events pop in time order, ties in insertion order, so a run
//! is a pure function of its inputs.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// A time-ordered queue of events at virtual nanoseconds.
#[derive(Debug)]
pub struct EventQueue<E> {
    heap: BinaryHeap<Reverse<(i64, u64)>>,
    events: std::collections::HashMap<u64, E>,
    next_seq: u64,
}

impl<E> Default for EventQueue<E> {
    fn default() -> Self {
        EventQueue {
            heap: BinaryHeap::new(),
            events: std::collections::HashMap::new(),
            next_seq: 0,
        }
    }
}

impl<E> EventQueue<E> {
    pub fn push(&mut self, at_ns: i64, event: E) {
        let seq = self.next_seq;
        self.next_seq += 1;
        self.heap.push(Reverse((at_ns, seq)));
        self.events.insert(seq, event);
    }

    /// The earliest event, with its time.
    pub fn pop(&mut self) -> Option<(i64, E)> {
        let Reverse((t, seq)) = self.heap.pop()?;
        let e = self.events.remove(&seq).expect("every queued seq has its event");
        Some((t, e))
    }

    pub fn peek_time(&self) -> Option<i64> {
        self.heap.peek().map(|Reverse((t, _))| *t)
    }

    pub fn len(&self) -> usize {
        self.heap.len()
    }

    pub fn is_empty(&self) -> bool {
        self.heap.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pops_in_time_order_with_ties_in_insertion_order() {
        let mut q = EventQueue::default();
        q.push(30, "c");
        q.push(10, "a1");
        q.push(20, "b");
        q.push(10, "a2");
        let order: Vec<_> = std::iter::from_fn(|| q.pop()).collect();
        assert_eq!(order, vec![(10, "a1"), (10, "a2"), (20, "b"), (30, "c")]);
        assert!(q.is_empty());
    }
}
