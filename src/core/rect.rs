//! Pixel and viewport rectangles shared by every feature and the pass tracker: scissors, render
//! areas, eye rects inside an image.
#![forbid(unsafe_code)]

/// A viewport in framebuffer pixels (`VkViewport` without depth).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewportRect {
    pub x: f32,
    pub y: f32,
    pub width: f32,
    pub height: f32,
}

/// A pixel rectangle (scissor, render area, image rect).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct PixelRect {
    pub x: i32,
    pub y: i32,
    pub width: u32,
    pub height: u32,
}

impl PixelRect {
    pub fn intersect(&self, o: &PixelRect) -> PixelRect {
        let x0 = self.x.max(o.x);
        let y0 = self.y.max(o.y);
        let x1 = (self.x as i64 + self.width as i64).min(o.x as i64 + o.width as i64);
        let y1 = (self.y as i64 + self.height as i64).min(o.y as i64 + o.height as i64);
        PixelRect { x: x0, y: y0, width: (x1 - x0 as i64).max(0) as u32, height: (y1 - y0 as i64).max(0) as u32 }
    }
    pub fn contains(&self, o: &PixelRect) -> bool {
        self.intersect(o) == *o
    }
    pub fn area(&self) -> u64 {
        self.width as u64 * self.height as u64
    }
    pub fn viewport(&self) -> ViewportRect {
        ViewportRect { x: self.x as f32, y: self.y as f32, width: self.width as f32, height: self.height as f32 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rect_ops() {
        let a = PixelRect { x: 0, y: 0, width: 10, height: 10 };
        let b = PixelRect { x: 5, y: -5, width: 10, height: 10 };
        assert_eq!(a.intersect(&b), PixelRect { x: 5, y: 0, width: 5, height: 5 });
        assert!(a.contains(&PixelRect { x: 1, y: 1, width: 2, height: 2 }));
        assert!(!a.contains(&b));
        assert_eq!(a.intersect(&PixelRect { x: 20, y: 0, width: 1, height: 1 }).area(), 0);
    }
}
