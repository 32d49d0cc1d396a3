//! An in-place sort with no panic path, for the kernels the firmware runs: the standard
//! library's `sort_unstable` keeps a call to `panic_on_ord_violation` (its answer to an `Ord`
//! that is not a total order) that no optimisation removes, and the firmware check links only
//! code without one (`tests/firmware/src/main.rs`). Compiled once for both precisions.

/// Sorts `items` in ascending order of `key`: heapsort (J. W. J. Williams, "Algorithm 232:
/// Heapsort", Communications of the ACM 7(6), 1964), in place, `O(n log n)` comparisons
/// whatever the input, nothing allocated, every access through `get` so that no index can
/// panic. Not stable: items of equal keys end in an order that depends only on the input
/// (deterministic), which is no order at all where equal keys mean equal items, as everywhere it
/// is used. An `Ord` that is not a total order gives some permutation, never a panic.
///
/// ```text
/// let mut pairs = [[3u32, 1], [1, 2], [2, 0], [1, 1]];
/// sort_by_key(&mut pairs, |&p| p);
/// assert_eq!(pairs, [[1, 1], [1, 2], [2, 0], [3, 1]]);
/// ```
pub(crate) fn sort_by_key<T: Copy, K: Ord>(items: &mut [T], key: impl Fn(&T) -> K) {
    let len = items.len();
    // The heap: every parent's key at least its children's.
    for root in (0..len / 2).rev() {
        sift_down(items, root, len, &key);
    }
    // Move the largest to the end of the shrinking heap.
    for end in (1..len).rev() {
        swap(items, 0, end);
        sift_down(items, 0, end, &key);
    }
}

/// Restores the heap order of `items[..end]` below `root`.
fn sift_down<T: Copy, K: Ord>(
    items: &mut [T],
    mut root: usize,
    end: usize,
    key: &impl Fn(&T) -> K,
) {
    let at = |items: &[T], i: usize| items.get(i).map(key);
    loop {
        // `2 root + 1` cannot overflow: `root < end / 2` or a child of one, and `end` is a
        // slice length.
        let left = 2 * root + 1;
        if left >= end {
            return;
        }
        let right = left + 1;
        let child = if right < end && at(items, left) < at(items, right) {
            right
        } else {
            left
        };
        if at(items, root) >= at(items, child) {
            return;
        }
        swap(items, root, child);
        root = child;
    }
}

/// Exchanges `items[i]` and `items[j]` (nothing if either is out of range).
#[inline]
fn swap<T: Copy>(items: &mut [T], i: usize, j: usize) {
    if let (Some(&a), Some(&b)) = (items.get(i), items.get(j)) {
        if let Some(slot) = items.get_mut(i) {
            *slot = b;
        }
        if let Some(slot) = items.get_mut(j) {
            *slot = a;
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::sort_by_key;
    use std::vec::Vec;

    #[test]
    fn sorts_as_the_standard_library_does() {
        // Against `sort_unstable` on pseudo-random inputs of every length up to 300, with
        // many repeated keys (values below 50) and without.
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for len in 0..300 {
            for modulus in [50u64, u64::MAX] {
                let items: Vec<[u32; 2]> = (0..len)
                    .map(|_| [(next() % modulus) as u32, (next() % modulus) as u32])
                    .collect();
                let mut ours = items.clone();
                sort_by_key(&mut ours, |&p| p);
                let mut reference = items;
                reference.sort_unstable();
                assert_eq!(ours, reference, "length {len}");
            }
        }
        let mut empty: [u8; 0] = [];
        sort_by_key(&mut empty, |&x| x);
    }
}
