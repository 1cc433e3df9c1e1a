//! A least-recently-used cache of per-node values under a byte budget, counted in frames: what
//! was used in the current frame is never evicted (it is being drawn), so a frame that needs
//! more than the budget holds more until the next frame. Decoded nodes in RAM ([`crate::Loader`])
//! and GPU buffers (myriad-render) both live in one.

use myriad_core::NodeKey;
use std::collections::HashMap;

struct Entry<V> {
    value: V,
    bytes: usize,
    last_used: u64,
}

pub struct Lru<V> {
    entries: HashMap<NodeKey, Entry<V>>,
    budget_bytes: usize,
    bytes: usize,
    frame: u64,
}

impl<V> Lru<V> {
    pub fn new(budget_bytes: usize) -> Lru<V> {
        Lru {
            entries: HashMap::new(),
            budget_bytes,
            bytes: 0,
            frame: 0,
        }
    }

    /// Starts a frame: what is touched or inserted from now on is in use.
    pub fn next_frame(&mut self) {
        self.frame += 1;
    }

    /// Marks `key` used in this frame; false if it is not here.
    pub fn touch(&mut self, key: &NodeKey) -> bool {
        match self.entries.get_mut(key) {
            Some(e) => {
                e.last_used = self.frame;
                true
            }
            None => false,
        }
    }

    /// Adds (or replaces) `key`, used in this frame, then evicts down to the budget.
    pub fn insert(&mut self, key: NodeKey, value: V, bytes: usize) {
        self.bytes += bytes;
        let e = Entry {
            value,
            bytes,
            last_used: self.frame,
        };
        if let Some(old) = self.entries.insert(key, e) {
            self.bytes -= old.bytes;
        }
        self.evict();
    }

    /// Drops least recently used entries until the cache fits its budget, sparing those used in
    /// the current frame.
    pub fn evict(&mut self) {
        if self.bytes <= self.budget_bytes {
            return;
        }
        let mut by_age: Vec<(u64, NodeKey)> = self
            .entries
            .iter()
            .filter(|(_, e)| e.last_used < self.frame)
            .map(|(k, e)| (e.last_used, *k))
            .collect();
        by_age.sort_unstable();
        for (_, k) in by_age {
            if self.bytes <= self.budget_bytes {
                break;
            }
            self.remove(&k);
        }
    }

    pub fn remove(&mut self, key: &NodeKey) -> Option<V> {
        let e = self.entries.remove(key)?;
        self.bytes -= e.bytes;
        Some(e.value)
    }

    pub fn clear(&mut self) {
        self.entries.clear();
        self.bytes = 0;
    }

    pub fn get(&self, key: &NodeKey) -> Option<&V> {
        self.entries.get(key).map(|e| &e.value)
    }
    pub fn contains(&self, key: &NodeKey) -> bool {
        self.entries.contains_key(key)
    }
    pub fn len(&self) -> usize {
        self.entries.len()
    }
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
    /// Bytes held (may exceed the budget by what the current frame uses).
    pub fn bytes(&self) -> usize {
        self.bytes
    }
    pub fn budget_bytes(&self) -> usize {
        self.budget_bytes
    }
    /// Every value held, in no order.
    pub fn values(&self) -> impl Iterator<Item = &V> {
        self.entries.values().map(|e| &e.value)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(i: u32) -> NodeKey {
        NodeKey::ROOT.child(i as usize % 8)
    }

    #[test]
    fn evicts_the_least_recently_used_and_spares_the_current_frame() {
        let mut c = Lru::new(30);
        c.next_frame();
        c.insert(key(0), "a", 10);
        c.insert(key(1), "b", 10);
        c.next_frame();
        c.insert(key(2), "c", 10);
        c.next_frame();
        assert!(c.touch(&key(0)));
        // Over budget: key 1 (last used in frame 1) goes first, then key 2 (frame 2); key 0 was
        // used in this frame and stays, as does the new one.
        c.insert(key(3), "d", 15);
        assert!(c.contains(&key(0)) && c.contains(&key(3)));
        assert!(!c.contains(&key(1)) && !c.contains(&key(2)));
        assert_eq!(c.bytes(), 25);
        // Everything in use: held over budget until the next frame.
        c.insert(key(4), "e", 20);
        assert_eq!((c.len(), c.bytes()), (3, 45));
        c.next_frame();
        c.touch(&key(4));
        c.evict();
        assert_eq!(c.bytes(), 20);
        assert_eq!(c.get(&key(4)), Some(&"e"));
        // Replacing counts the new size only.
        c.insert(key(4), "f", 5);
        assert_eq!(c.bytes(), 5);
        assert_eq!(c.remove(&key(4)), Some("f"));
        assert!(c.is_empty() && c.bytes() == 0);
    }
}
