//! Text in PNG pictures, laid out right. plotters' bitmap text (0.3, through `ab_glyph`) draws
//! each glyph's ink box at the pen position, dropping the glyph's left side bearing, and rounds
//! the pen to whole pixels glyph by glyph: letters crowd or drift apart (`obs ervation`,
//! `l og`). [`Kerned`] is the bitmap backend with its own `draw_text`: the pen advances by
//! each glyph's advance and kerning in fractions of a pixel, and each glyph is placed by its
//! own bounds. Everything else is the bitmap backend's.

use ab_glyph::{Font, FontRef, PxScale, ScaleFont};
use plotters_backend::text_anchor::{HPos, VPos};
use plotters_backend::{
    BackendColor, BackendCoord, BackendStyle, BackendTextStyle, DrawingBackend, DrawingErrorKind,
};

/// A drawing backend (the bitmap one) whose text is laid out by [`layout`].
pub struct Kerned<B>(pub B);

/// Where the glyphs of `text` at `size` pixels go: each inked pixel `(x, y, coverage)`, from
/// the top left of the text's box (the box plotters measures: its width the sum of the
/// advances and kernings, its height `size / 1.24`; the baseline at half the size, as plotters
/// places it).
pub fn layout(text: &str, size: f64) -> Vec<(i32, i32, f32)> {
    let Ok(font) = FontRef::try_from_slice(crate::FONT) else {
        return Vec::new();
    };
    let scale = PxScale::from(size as f32);
    let scaled = font.as_scaled(scale);
    let mut pen = 0f32;
    let mut prev = None;
    let mut out = Vec::new();
    for c in text.chars() {
        let id = scaled.glyph_id(c);
        if let Some(p) = prev {
            pen += scaled.kern(p, id);
        }
        prev = Some(id);
        let glyph = id.with_scale_and_position(scale, ab_glyph::point(pen, 0.0));
        if let Some(g) = scaled.outline_glyph(glyph) {
            let b = g.px_bounds();
            let (left, top) = (b.min.x as i32, (size as f32 / 2.0 + b.min.y) as i32);
            g.draw(|x, y, c| out.push((left + x as i32, top + y as i32, c.min(1.0))));
        }
        pen += scaled.h_advance(id);
    }
    out
}

impl<B: DrawingBackend> DrawingBackend for Kerned<B> {
    type ErrorType = B::ErrorType;

    fn get_size(&self) -> (u32, u32) {
        self.0.get_size()
    }

    fn ensure_prepared(&mut self) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.0.ensure_prepared()
    }

    fn present(&mut self) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.0.present()
    }

    fn draw_pixel(
        &mut self,
        point: BackendCoord,
        color: BackendColor,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.0.draw_pixel(point, color)
    }

    fn draw_line<S: BackendStyle>(
        &mut self,
        from: BackendCoord,
        to: BackendCoord,
        style: &S,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.0.draw_line(from, to, style)
    }

    fn draw_rect<S: BackendStyle>(
        &mut self,
        upper_left: BackendCoord,
        bottom_right: BackendCoord,
        style: &S,
        fill: bool,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.0.draw_rect(upper_left, bottom_right, style, fill)
    }

    fn draw_path<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        path: I,
        style: &S,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.0.draw_path(path, style)
    }

    fn draw_circle<S: BackendStyle>(
        &mut self,
        center: BackendCoord,
        radius: u32,
        style: &S,
        fill: bool,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.0.draw_circle(center, radius, style, fill)
    }

    fn fill_polygon<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        vert: I,
        style: &S,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.0.fill_polygon(vert, style)
    }

    fn blit_bitmap(
        &mut self,
        pos: BackendCoord,
        size: (u32, u32),
        src: &[u8],
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.0.blit_bitmap(pos, size, src)
    }

    fn estimate_text_size<S: BackendTextStyle>(
        &self,
        text: &str,
        style: &S,
    ) -> Result<(u32, u32), DrawingErrorKind<Self::ErrorType>> {
        self.0.estimate_text_size(text, style)
    }

    fn draw_text<S: BackendTextStyle>(
        &mut self,
        text: &str,
        style: &S,
        pos: BackendCoord,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        let color = style.color();
        if color.alpha == 0.0 {
            return Ok(());
        }
        // The box and the anchor exactly as the default `draw_text` takes them.
        let ((min_x, min_y), (max_x, max_y)) = style
            .layout_box(text)
            .map_err(|e| DrawingErrorKind::FontError(Box::new(e)))?;
        let (width, height) = (max_x - min_x, max_y - min_y);
        let dx = match style.anchor().h_pos {
            HPos::Left => 0,
            HPos::Right => -width,
            HPos::Center => -width / 2,
        };
        let dy = match style.anchor().v_pos {
            VPos::Top => 0,
            VPos::Center => -height / 2,
            VPos::Bottom => -height,
        };
        let trans = style.transform();
        let (w, h) = self.get_size();
        for (x, y, coverage) in layout(text, style.size()) {
            let (x, y) = trans.transform(x + dx - min_x, y + dy - min_y);
            let (x, y) = (pos.0 + x, pos.1 + y);
            if x >= 0 && x < w as i32 && y >= 0 && y < h as i32 {
                self.0.draw_pixel(
                    (x, y),
                    BackendColor {
                        alpha: color.alpha * coverage as f64,
                        rgb: color.rgb,
                    },
                )?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The first inked column of `text`, and the last.
    fn ink(text: &str, size: f64) -> (i32, i32) {
        let px = layout(text, size);
        (
            px.iter().map(|p| p.0).min().unwrap(),
            px.iter().map(|p| p.0).max().unwrap(),
        )
    }

    #[test]
    fn glyphs_keep_their_side_bearings_and_fractional_advances() {
        // `o` is inked from its left side bearing (over a pixel at 28 px), not from the pen
        // position as plotters draws it.
        assert!(ink("o", 28.0).0 >= 1, "{:?}", ink("o", 28.0));
        // Ten `i`s: the last one's ink starts where nine fractional advances put it (to a
        // pixel), not nine rounded ones.
        let font = FontRef::try_from_slice(crate::FONT).unwrap();
        let scaled = font.as_scaled(PxScale::from(13.0));
        let advance = scaled.h_advance(scaled.glyph_id('i'));
        let one = ink("i", 13.0).0;
        let last = ink("iiiiiiiiii", 13.0).1 - (ink("i", 13.0).1 - one);
        let expected = one as f32 + 9.0 * advance;
        assert!(
            (last as f32 - expected).abs() <= 1.0,
            "{last} vs {expected}"
        );
    }
}
