#include "hex_element.h"

#include <cmath>

#include <glm/geometric.hpp>
#include <glm/matrix.hpp>

namespace bisturi::sim {

namespace {

/// Gradient of corner c's shape function on the unit cube at xi (reference coordinates).
glm::dvec3 unit_gradient(int c, const glm::dvec3& xi) {
  const glm::dvec3 s((c & 1) ? xi.x : 1.0 - xi.x, ((c >> 1) & 1) ? xi.y : 1.0 - xi.y,
                     ((c >> 2) & 1) ? xi.z : 1.0 - xi.z);
  const glm::dvec3 d((c & 1) ? 1.0 : -1.0, ((c >> 1) & 1) ? 1.0 : -1.0,
                     ((c >> 2) & 1) ? 1.0 : -1.0);
  return {d.x * s.y * s.z, s.x * d.y * s.z, s.x * s.y * d.z};
}

/// <G_i,a G_j,b> over the unit cube: by 2x2x2 Gauss (full) and at the centre (reduced).
struct UnitIntegrals {
  double full[8][8][3][3];
  double centre[8][8][3][3];
  UnitIntegrals() {
    const double g = 0.5 / std::sqrt(3.0);
    for (int i = 0; i < 8; ++i)
      for (int j = 0; j < 8; ++j)
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b)
            full[i][j][a][b] = centre[i][j][a][b] = 0.0;
    for (int q = 0; q < 8; ++q) {
      const glm::dvec3 xi(0.5 + ((q & 1) ? g : -g), 0.5 + (((q >> 1) & 1) ? g : -g),
                          0.5 + (((q >> 2) & 1) ? g : -g));
      for (int i = 0; i < 8; ++i) {
        const glm::dvec3 gi = unit_gradient(i, xi);
        for (int j = 0; j < 8; ++j) {
          const glm::dvec3 gj = unit_gradient(j, xi);
          for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b)
              full[i][j][a][b] += 0.125 * gi[a] * gj[b];
        }
      }
    }
    for (int i = 0; i < 8; ++i) {
      const glm::dvec3 gi = unit_gradient(i, glm::dvec3(0.5));
      for (int j = 0; j < 8; ++j) {
        const glm::dvec3 gj = unit_gradient(j, glm::dvec3(0.5));
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b)
            centre[i][j][a][b] = gi[a] * gj[b];
      }
    }
  }
};

const UnitIntegrals& unit_integrals() {
  static const UnitIntegrals u;
  return u;
}

}  // namespace

void box_stiffness(const glm::dvec3& h, double mu, double lambda, double scale, HexStiffness& k) {
  const UnitIntegrals& u = unit_integrals();
  const double volume = h.x * h.y * h.z * scale;
  const glm::dvec3 inv(1.0 / h.x, 1.0 / h.y, 1.0 / h.z);
  for (int i = 0; i < 8; ++i) {
    for (int j = 0; j < 8; ++j) {
      double dot = 0.0;  // grad N_i . grad N_j, integrated
      for (int c = 0; c < 3; ++c)
        dot += u.full[i][j][c][c] * inv[c] * inv[c];
      glm::dmat3& m = k[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)];
      for (int a = 0; a < 3; ++a) {
        for (int b = 0; b < 3; ++b) {
          const double s = inv[a] * inv[b];
          // K_ij^ab = lambda dN_i/dx_a dN_j/dx_b + mu dN_i/dx_b dN_j/dx_a + mu delta_ab grad.grad
          double v = lambda * u.centre[i][j][a][b] * s + mu * u.full[i][j][b][a] * s;
          if (a == b) v += mu * dot;
          m[b][a] = volume * v;  // glm: column b, row a
        }
      }
    }
  }
}

std::array<glm::dvec3, 8> centre_gradients(const glm::dvec3& h) {
  std::array<glm::dvec3, 8> g;
  for (int c = 0; c < 8; ++c)
    g[static_cast<std::size_t>(c)] = unit_gradient(c, glm::dvec3(0.5)) / h;
  return g;
}

std::array<std::array<glm::dvec3, 8>, 8> gauss_gradients(const glm::dvec3& h) {
  const double g = 0.5 / std::sqrt(3.0);
  std::array<std::array<glm::dvec3, 8>, 8> out;
  for (int q = 0; q < 8; ++q) {
    const glm::dvec3 xi(0.5 + ((q & 1) ? g : -g), 0.5 + (((q >> 1) & 1) ? g : -g),
                        0.5 + (((q >> 2) & 1) ? g : -g));
    for (int c = 0; c < 8; ++c)
      out[static_cast<std::size_t>(q)][static_cast<std::size_t>(c)] = unit_gradient(c, xi) / h;
  }
  return out;
}

namespace {

/// det F, floored where the element collapses, and F^-T computed from that floor.
double safe_det(const glm::dmat3& f, glm::dmat3& inv_t) {
  double j = glm::determinant(f);
  if (j > 1e-2) {
    inv_t = glm::transpose(glm::inverse(f));
    return j;
  }
  // Collapsed: the stress of a small positive J along F's own directions.
  inv_t = glm::transpose(glm::inverse(f + glm::dmat3(1e-2)));
  return 1e-2;
}

}  // namespace

glm::dmat3 neo_hookean_isochoric_stress(const glm::dmat3& f, double mu) {
  glm::dmat3 inv_t;
  const double j = safe_det(f, inv_t);
  double i1 = 0.0;
  for (int c = 0; c < 3; ++c)
    i1 += glm::dot(f[c], f[c]);
  // d/dF of (mu/2)(J^-2/3 I1 - 3) = mu J^-2/3 (F - I1/3 F^-T)
  return mu * std::pow(j, -2.0 / 3.0) * (f - (i1 / 3.0) * inv_t);
}

glm::dmat3 neo_hookean_volumetric_stress(const glm::dmat3& f, double bulk) {
  glm::dmat3 inv_t;
  const double j = safe_det(f, inv_t);
  // d/dF of (K/2)(J - 1)^2 = K (J - 1) J F^-T
  return bulk * (j - 1.0) * j * inv_t;
}

glm::dmat3 polar_rotation(const glm::dmat3& f) {
  // The Newton iteration R <- (R + R^-T) / 2 (Higham 1986): quadratic convergence to the
  // orthogonal factor of a non-singular F.
  glm::dmat3 r = f;
  for (int it = 0; it < 30; ++it) {
    const double det = glm::determinant(r);
    if (!(std::abs(det) > 1e-300) || !std::isfinite(det)) return glm::dmat3(1.0);
    const glm::dmat3 next = 0.5 * (r + glm::transpose(glm::inverse(r)));
    double change = 0.0;
    for (int c = 0; c < 3; ++c)
      for (int rr = 0; rr < 3; ++rr)
        change = std::max(change, std::abs(next[c][rr] - r[c][rr]));
    r = next;
    if (change < 1e-12) break;
  }
  if (glm::determinant(r) < 0.0) return glm::dmat3(1.0);  // an inverted element: no rotation
  return r;
}

}  // namespace bisturi::sim
