// The affine map between a cutout's pixels and the tangent plane (u, v) on the sky, in arcsec, in
// which a multi-epoch model lives (MEDS's WCS Jacobian, ../shared/reference/survey-formats.md):
//   (u, v) = J ((x, y) - (x_ref, y_ref)),   J = [[du/dx, du/dy], [dv/dx, dv/dy]],
// x the column and y the row (0-based, pixel centres at integers), (x_ref, y_ref) the pixel where
// (u, v) = 0 (the object's position in the cutout). A model in (u, v) seen through a cutout is the
// same profile in pixels: its quadratic form becomes J^T Q J, its centre x_ref + J^-1 (u0, v0),
// its flux stays (the surface brightness per arcsec^2 times the pixel's area). The identity frame
// is the single-stamp fit's: the model in pixels of the stamp.
#pragma once

#include "kernels/ellipse.hpp"

namespace stampede {

struct PixelFrame {
  double dudx = 1, dudy = 0, dvdx = 0, dvdy = 1;
  double x_ref = 0, y_ref = 0;

  // From MEDS's columns (rows and columns): du/dx = dudcol, du/dy = dudrow, and likewise for v.
  static PixelFrame from_meds(double dudrow, double dudcol, double dvdrow, double dvdcol, double cutout_row,
                              double cutout_col) {
    return {dudcol, dudrow, dvdcol, dvdrow, cutout_col, cutout_row};
  }
  // J is the unit matrix: (u, v) are pixel offsets from the reference.
  bool unit_jacobian() const { return dudx == 1 && dudy == 0 && dvdx == 0 && dvdy == 1; }
  bool identity() const { return unit_jacobian() && x_ref == 0 && y_ref == 0; }
  double determinant() const { return dudx * dvdy - dudy * dvdx; }  // arcsec^2 per pixel (signed)

  // The pixel at which (u, v) lands, and the inverse map's matrix d(x, y) / d(u, v).
  void to_pixel(double u, double v, double* x, double* y) const {
    const double d = determinant();
    *x = x_ref + (dvdy * u - dudy * v) / d;
    *y = y_ref + (-dvdx * u + dudx * v) / d;
  }
  void inverse(double m[2][2]) const {
    const double d = determinant();
    m[0][0] = dvdy / d, m[0][1] = -dudy / d, m[1][0] = -dvdx / d, m[1][1] = dudx / d;
  }
  // A quadratic form in pixel offsets as one in (u, v): J^-T Q J^-1.
  kernels::EllipseQuadratic to_sky(const kernels::EllipseQuadratic& q) const {
    double m[2][2];
    inverse(m);
    auto form = [&](double ax, double ay, double bx, double by) {
      return ax * (q.xx * bx + q.xy * by) + ay * (q.xy * bx + q.yy * by);
    };
    return {form(m[0][0], m[1][0], m[0][0], m[1][0]), form(m[0][0], m[1][0], m[0][1], m[1][1]),
            form(m[0][1], m[1][1], m[0][1], m[1][1])};
  }
  // A quadratic form in (u, v) as one in pixel offsets: J^T Q J.
  kernels::EllipseQuadratic to_pixel(const kernels::EllipseQuadratic& q) const {
    // Columns of J: a = (dudx, dvdx), b = (dudy, dvdy); (J^T Q J)_ij = col_i^T Q col_j.
    auto form = [&](double ax, double ay, double bx, double by) {
      return ax * (q.xx * bx + q.xy * by) + ay * (q.xy * bx + q.yy * by);
    };
    return {form(dudx, dvdx, dudx, dvdx), form(dudx, dvdx, dudy, dvdy), form(dudy, dvdy, dudy, dvdy)};
  }
};

}  // namespace stampede
