//! A worker's cache of decoded split objects, like a warm function container keeping what it
//! loaded: split objects are written once by the plan step and never change within a job, so a
//! decoded split can serve every later task of the same job on the same worker. Output bytes
//! do not depend on whether a split came from the cache.
//!
//! Textures are found through it as well: a texture a cached split holds serves every other
//! split that uses it (one copy per container), and goes when the last split holding it goes.
//!
//! It keeps the last few job plans too: `plan.json` is written once per job (a rebuilt one has
//! the same bytes), so a warm worker reads and parses it once per job instead of once per task
//! (a quarter of the S3 requests of a staged job).

use super::plan::JobPlan;
use super::split_object::SplitObject;
use crate::texture::Texture;
use std::sync::{Arc, Mutex, Weak};

/// Least-recently-used cache of decoded splits, bounded by the memory they hold
/// ([`SplitObject::memory_bytes`]).
#[derive(Debug)]
pub struct SplitCache {
    budget_bytes: u64,
    entries: Mutex<Vec<Entry>>,
    /// The last [`PLANS_KEPT`] plans used, newest last, by their `plan.json` key.
    plans: Mutex<Vec<(String, Arc<JobPlan>)>>,
    /// Textures by object key, alive while some split (cached or in use) holds them.
    textures: Mutex<Vec<(String, Weak<Texture>)>>,
}

/// Plans a cache keeps (a worker serves one job at a time, rarely a few interleaved).
const PLANS_KEPT: usize = 4;

#[derive(Debug)]
struct Entry {
    key: String,
    bytes: u64,
    object: Arc<SplitObject>,
}

impl SplitCache {
    /// A cache holding decoded splits of at most `budget_bytes` bytes of memory in total, and
    /// the last few plans (0 disables both).
    pub fn new(budget_bytes: u64) -> SplitCache {
        SplitCache {
            budget_bytes,
            entries: Mutex::new(Vec::new()),
            plans: Mutex::new(Vec::new()),
            textures: Mutex::new(Vec::new()),
        }
    }

    /// The cached split stored under `key`, marking it most recently used.
    pub fn get(&self, key: &str) -> Option<Arc<SplitObject>> {
        let mut entries = self.entries.lock().unwrap_or_else(|e| e.into_inner());
        let i = entries.iter().position(|e| e.key == key)?;
        let entry = entries.remove(i);
        let object = Arc::clone(&entry.object);
        entries.push(entry);
        Some(object)
    }

    /// Memory the cached splits hold now ([`SplitObject::memory_bytes`] summed): part of a
    /// warm container's memory whatever task it runs.
    pub fn resident_bytes(&self) -> u64 {
        let entries = self.entries.lock().unwrap_or_else(|e| e.into_inner());
        entries.iter().map(|e| e.bytes).sum()
    }

    /// Evicts the least recently used splits until the rest hold at most `bytes`: room for a
    /// task that needs the remainder of its function's memory.
    pub fn trim_to(&self, bytes: u64) {
        self.trim_to_keeping(bytes, &|_| false);
    }

    /// [`SplitCache::trim_to`] for the splits `keep` does not name: the least recently used of
    /// those go until they hold at most `bytes`; the ones `keep` names (those the next task
    /// reads, already part of its own memory) stay.
    pub fn trim_to_keeping(&self, bytes: u64, keep: &dyn Fn(&str) -> bool) {
        let mut entries = self.entries.lock().unwrap_or_else(|e| e.into_inner());
        let others = |entries: &Vec<Entry>| -> u64 {
            entries
                .iter()
                .filter(|e| !keep(&e.key))
                .map(|e| e.bytes)
                .sum()
        };
        while others(&entries) > bytes {
            let Some(oldest) = entries.iter().position(|e| !keep(&e.key)) else {
                break;
            };
            entries.remove(oldest);
        }
    }

    /// Keeps `object` (stored under `key`), evicting the least recently used.
    pub fn insert(&self, key: &str, object: Arc<SplitObject>) {
        let bytes = object.memory_bytes();
        if bytes > self.budget_bytes {
            return;
        }
        let mut entries = self.entries.lock().unwrap_or_else(|e| e.into_inner());
        entries.retain(|e| e.key != key);
        entries.push(Entry {
            key: key.to_string(),
            bytes,
            object,
        });
        while entries.iter().map(|e| e.bytes).sum::<u64>() > self.budget_bytes {
            entries.remove(0);
        }
    }
}

impl SplitCache {
    /// The texture stored under `key`, if a split still holds it.
    pub fn texture(&self, key: &str) -> Option<Arc<Texture>> {
        let textures = self.textures.lock().unwrap_or_else(|e| e.into_inner());
        textures
            .iter()
            .find(|(k, _)| k == key)
            .and_then(|(_, t)| t.upgrade())
    }

    /// Remembers `texture`, read from `key`, for as long as something holds it (nothing when
    /// the cache is disabled); forgets textures nothing holds any more.
    pub fn insert_texture(&self, key: &str, texture: &Arc<Texture>) {
        if self.budget_bytes == 0 {
            return;
        }
        let mut textures = self.textures.lock().unwrap_or_else(|e| e.into_inner());
        textures.retain(|(k, t)| k != key && t.strong_count() > 0);
        textures.push((key.to_owned(), Arc::downgrade(texture)));
    }

    /// The plan cached under `key` (a `plan.json` key), if any.
    pub fn plan(&self, key: &str) -> Option<Arc<JobPlan>> {
        let plans = self.plans.lock().unwrap_or_else(|e| e.into_inner());
        plans
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, p)| Arc::clone(p))
    }

    /// Keeps `plan`, read from `key`, dropping the oldest beyond [`PLANS_KEPT`]; nothing when
    /// the cache is disabled.
    pub fn insert_plan(&self, key: &str, plan: Arc<JobPlan>) {
        if self.budget_bytes == 0 {
            return;
        }
        let mut plans = self.plans.lock().unwrap_or_else(|e| e.into_inner());
        plans.retain(|(k, _)| k != key);
        plans.push((key.to_owned(), plan));
        if plans.len() > PLANS_KEPT {
            plans.remove(0);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::Bvh;
    use crate::pipeline::TriangleShading;

    /// A split of `n` triangles.
    fn object(split: u32, n: usize) -> Arc<SplitObject> {
        let tri = [glam::Vec3::ZERO, glam::Vec3::X, glam::Vec3::Y];
        Arc::new(SplitObject {
            split,
            bvh: Bvh::build(vec![tri; n], (0..n as u32).collect()),
            shading: vec![
                TriangleShading {
                    normals: None,
                    kd: [0.5; 3],
                    texture: None,
                };
                n
            ]
            .into_iter()
            .collect(),
            textures: Default::default(),
        })
    }

    #[test]
    fn evicts_least_recently_used_within_its_memory_budget() {
        let size = object(0, 10).memory_bytes();
        assert!(
            size > 10 * 36,
            "a split holds at least its corners ({size})"
        );
        let cache = SplitCache::new(size * 5 / 2);
        cache.insert("a", object(0, 10));
        cache.insert("b", object(1, 10));
        assert_eq!(cache.resident_bytes(), 2 * size);
        assert!(cache.get("a").is_some());
        cache.insert("c", object(2, 10));
        assert!(cache.get("b").is_none(), "b was least recently used");
        assert_eq!(cache.get("a").unwrap().split, 0);
        assert_eq!(cache.get("c").unwrap().split, 2);
        cache.insert("huge", object(3, 100));
        assert!(cache.get("huge").is_none(), "larger than the whole budget");
        assert_eq!(
            cache.get("a").unwrap().split,
            0,
            "kept when a huge one is refused"
        );
        assert_eq!(cache.resident_bytes(), 2 * size, "a and c");
        cache.trim_to(2 * size);
        assert_eq!(cache.resident_bytes(), 2 * size, "already within");
        cache.trim_to(2 * size - 1);
        assert!(cache.get("c").is_none(), "c was least recently used");
        assert_eq!(cache.get("a").unwrap().split, 0);
        cache.trim_to(0);
        assert_eq!(cache.resident_bytes(), 0);
        assert!(SplitCache::new(0).get("a").is_none());
    }

    /// The splits the next task reads stay whatever the limit; the others go, least recently
    /// used first, until they fit it.
    #[test]
    fn trimming_keeps_the_splits_the_next_task_reads() {
        let size = object(0, 10).memory_bytes();
        let cache = SplitCache::new(size * 3);
        for (key, split) in [("a", 0), ("b", 1), ("c", 2)] {
            cache.insert(key, object(split, 10));
        }
        cache.trim_to_keeping(size, &|key| key == "a");
        assert!(cache.get("a").is_some(), "kept: the next task reads it");
        assert!(
            cache.get("b").is_none(),
            "the least recently used other one"
        );
        assert!(cache.get("c").is_some(), "the others fit the limit");
        cache.trim_to_keeping(0, &|key| key == "c");
        assert!(cache.get("a").is_none());
        assert_eq!(cache.resident_bytes(), size, "only c");
    }
}
