//! A tree of axis-aligned cuts: the geometric answer of RCB, queried for the
//! owner of a point and the ranks a box overlaps.

use crate::Aabb;

#[derive(Debug, Clone, PartialEq)]
pub enum Node {
    Leaf(i32),
    /// Points with `x[dim] <= value` go left; the plane `x[dim] == value`
    /// bounds both sides' closed regions (items on it may be dealt to
    /// either).
    Cut {
        dim: usize,
        value: f64,
        left: usize,
        right: usize,
    },
}

#[derive(Debug, Clone, PartialEq)]
pub struct CutTree {
    pub nodes: Vec<Node>,
}

impl CutTree {
    /// Owner rank of a point.
    #[inline]
    pub fn owner(&self, p: [f64; 3]) -> i32 {
        let mut n = 0;
        loop {
            match self.nodes[n] {
                Node::Leaf(r) => return r,
                Node::Cut {
                    dim,
                    value,
                    left,
                    right,
                } => n = if p[dim] <= value { left } else { right },
            }
        }
    }

    /// Appends the ranks whose closed region overlaps the closed box `b`.
    #[inline]
    pub fn ranks_overlapping(&self, b: &Aabb, out: &mut Vec<i32>) {
        self.visit(0, b, out);
    }

    // Recursion depth is the tree depth, log2 of the ranks: no stack to set up.
    fn visit(&self, n: usize, b: &Aabb, out: &mut Vec<i32>) {
        match self.nodes[n] {
            Node::Leaf(r) => out.push(r),
            Node::Cut {
                dim,
                value,
                left,
                right,
            } => {
                if b.lo[dim] <= value {
                    self.visit(left, b, out);
                }
                if b.hi[dim] >= value {
                    self.visit(right, b, out);
                }
            }
        }
    }
}
