//! Structural checks of a built BVH, run after every build in debug builds.

use super::Bvh;
use crate::geometry::PrimKind;

impl Bvh {
    /// Every BVH primitive referenced by exactly one leaf; children inside their
    /// parent; leaves of one kind with in-range primitives inside their box; the tree
    /// within the traversal stack; every object index in range of the arrays.
    pub fn validate(&self) -> Result<(), String> {
        let p = &self.prims;
        if p.spheres.len() != p.sphere_obj.len()
            || p.triangles.len() != p.triangle_obj.len()
            || p.quadrics.len() != p.quadric_obj.len()
            || p.free_quadrics.len() != p.free_quadric_obj.len()
        {
            return Err("primitive and object arrays differ in length".into());
        }
        let total: usize = PrimKind::BVH_KINDS.iter().map(|&k| p.len(k)).sum();
        if self.nodes.is_empty() {
            return if total == 0 {
                Ok(())
            } else {
                Err(format!("{total} primitives but no nodes"))
            };
        }
        let mut seen: Vec<Vec<u8>> = PrimKind::BVH_KINDS
            .iter()
            .map(|&k| vec![0; p.len(k)])
            .collect();
        let mut stack = vec![(0usize, 1usize)];
        while let Some((i, depth)) = stack.pop() {
            if depth >= super::STACK_SIZE {
                return Err(format!("node {i} at depth {depth} exceeds the stack"));
            }
            let n = &self.nodes[i];
            let b = n.bounds();
            if n.is_leaf() {
                let kind = n.kind();
                let Some(k) = PrimKind::BVH_KINDS.iter().position(|&b| b == kind) else {
                    return Err(format!("leaf {i} has non-BVH kind {kind:?}"));
                };
                let (first, count) = (n.first as usize, n.count() as usize);
                if first + count > p.len(kind) {
                    return Err(format!("leaf {i} range {first}+{count} out of bounds"));
                }
                for (j, s) in seen[k].iter_mut().enumerate().skip(first).take(count) {
                    if !b.contains(&p.bounds(kind, j)) {
                        return Err(format!("leaf {i}: primitive {j} outside the box"));
                    }
                    *s += 1;
                }
            } else {
                let l = n.first as usize;
                if l + 1 >= self.nodes.len() || l <= i {
                    return Err(format!("node {i}: child index {l} out of order"));
                }
                for c in [l, l + 1] {
                    if !b.contains(&self.nodes[c].bounds()) {
                        return Err(format!("node {c} not inside its parent {i}"));
                    }
                    stack.push((c, depth + 1));
                }
            }
        }
        for (k, s) in seen.iter().enumerate() {
            if let Some(j) = s.iter().position(|&c| c != 1) {
                return Err(format!(
                    "primitive {j} of kind {k} referenced {} times",
                    s[j]
                ));
            }
        }
        Ok(())
    }
}
