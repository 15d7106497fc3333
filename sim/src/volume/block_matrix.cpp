#include "block_matrix.h"

#include "../hot_loop.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include <glm/geometric.hpp>
#include <glm/matrix.hpp>

namespace bisturi::sim {

BlockMatrix::BlockMatrix(std::size_t nodes, std::span<const std::array<std::uint32_t, 8>> cells) {
  // Each node's cells (compressed rows), then its row: the nodes of those cells, in order.
  std::vector<std::uint32_t> first_cell(nodes + 1, 0);
  for (const auto& cell : cells)
    for (const std::uint32_t a : cell)
      ++first_cell[a + 1];
  for (std::size_t i = 0; i < nodes; ++i)
    first_cell[i + 1] += first_cell[i];
  std::vector<std::uint32_t> node_cells(first_cell.back());
  std::vector<std::uint32_t> filled(first_cell.begin(), first_cell.end() - 1);
  for (std::size_t c = 0; c < cells.size(); ++c)
    for (const std::uint32_t a : cells[c])
      node_cells[filled[a]++] = static_cast<std::uint32_t>(c);
  row_start_.assign(nodes + 1, 0);
  diagonal_.resize(nodes);
  columns_.clear();
  columns_.reserve(27 * nodes);  // an inner node of a regular lattice
  cell_slots_.resize(cells.size());
  std::vector<std::uint32_t> row;
  // Per node, in the row being built: its column's slot, and the row that listed it last.
  std::vector<std::uint32_t> slot_of(nodes, 0), listed_in(nodes, UINT32_MAX);
  for (std::size_t i = 0; i < nodes; ++i) {
    row.clear();
    for (std::uint32_t k = first_cell[i]; k < first_cell[i + 1]; ++k)
      for (const std::uint32_t j : cells[node_cells[k]]) {
        if (listed_in[j] == i) continue;
        listed_in[j] = static_cast<std::uint32_t>(i);
        row.push_back(j);
      }
    if (row.empty()) row.push_back(static_cast<std::uint32_t>(i));  // in no cell: held alone
    std::sort(row.begin(), row.end());
    for (const std::uint32_t j : row) {
      if (j == i) diagonal_[i] = static_cast<std::uint32_t>(columns_.size());
      slot_of[j] = static_cast<std::uint32_t>(columns_.size());
      columns_.push_back(j);
    }
    row_start_[i + 1] = static_cast<std::uint32_t>(columns_.size());
    // The slots of this row in each of its cells' blocks (the row of the corner that is i).
    for (std::uint32_t k = first_cell[i]; k < first_cell[i + 1]; ++k) {
      const auto& cell = cells[node_cells[k]];
      for (std::size_t a = 0; a < 8; ++a) {
        if (cell[a] != i) continue;
        for (std::size_t b = 0; b < 8; ++b)
          cell_slots_[node_cells[k]][a * 8 + b] = slot_of[cell[b]];
      }
    }
  }
  values_.assign(columns_.size(), std::array<float, 12>{});
  r_.resize(nodes);
  z_.resize(nodes);
  p_.resize(nodes);
  q_.resize(nodes);
  inv_diag_.resize(nodes);
  x_single_.resize(nodes);
}

void BlockMatrix::set_zero() {
  std::fill(values_.begin(), values_.end(), std::array<float, 12>{});
}

namespace {

using Lanes = float __attribute__((vector_size(16)));

/// y = A x over rows [0, n), in single precision, a block's column as one 4-wide vector: each
/// row's sum of a few dozen products carries far less rounding than the solve's tolerance.
BISTURI_HOT void multiply_rows(std::size_t n, const std::uint32_t* row_start,
                               const std::uint32_t* columns, const std::array<float, 12>* values,
                               const std::array<float, 4>* x, glm::dvec3* y) {
  for (std::size_t i = 0; i < n; ++i) {
    Lanes sum = {0.0f, 0.0f, 0.0f, 0.0f};
    for (std::uint32_t s = row_start[i]; s < row_start[i + 1]; ++s) {
      Lanes c0, c1, c2;
      std::memcpy(&c0, values[s].data(), sizeof c0);
      std::memcpy(&c1, values[s].data() + 4, sizeof c1);
      std::memcpy(&c2, values[s].data() + 8, sizeof c2);
      const std::array<float, 4>& v = x[columns[s]];
      sum += c0 * v[0] + c1 * v[1] + c2 * v[2];
    }
    y[i] = glm::dvec3(sum[0], sum[1], sum[2]);
  }
}

}  // namespace

glm::mat3 BlockMatrix::block(std::uint32_t slot) const {
  glm::mat3 m;
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r)
      m[c][r] = values_[slot][4 * c + r];
  return m;
}

void BlockMatrix::multiply(std::span<const glm::dvec3> x, std::span<glm::dvec3> y) const {
  const std::size_t n = nodes();
  for (std::size_t i = 0; i < n; ++i)
    x_single_[i] = {float(x[i].x), float(x[i].y), float(x[i].z), 0.0f};
  multiply_rows(n, row_start_.data(), columns_.data(), values_.data(), x_single_.data(), y.data());
}

void BlockMatrix::expand(std::span<glm::dvec3> x, std::span<const HangingNode> hanging) {
  for (const HangingNode& h : hanging) {
    glm::dvec3 sum(0.0);
    for (std::uint32_t m = 0; m < h.masters_count; ++m)
      sum += h.weights[m] * x[h.masters[m]];
    x[h.node] = sum;
  }
}

void BlockMatrix::restrict_to_masters(std::span<glm::dvec3> v,
                                      std::span<const HangingNode> hanging) {
  for (const HangingNode& h : hanging) {
    for (std::uint32_t m = 0; m < h.masters_count; ++m)
      v[h.masters[m]] += h.weights[m] * v[h.node];
    v[h.node] = glm::dvec3(0.0);
  }
}

BlockMatrix::SolveStats BlockMatrix::solve(std::span<const glm::dvec3> b, std::span<glm::dvec3> x,
                                           std::span<const std::uint8_t> fixed_nodes,
                                           double tolerance, int max_iterations,
                                           std::span<const HangingNode> hanging) {
  const std::size_t n = nodes();
  // Hanging nodes are no unknowns: held at zero in y, as fixed ones are.
  std::span<const std::uint8_t> fixed = fixed_nodes;
  if (!hanging.empty()) {
    held_or_hanging_.assign(fixed_nodes.begin(), fixed_nodes.end());
    for (const HangingNode& h : hanging)
      held_or_hanging_[h.node] = 1;
    fixed = held_or_hanging_;
  }
  const auto dot = [&](const std::vector<glm::dvec3>& u, const std::vector<glm::dvec3>& v) {
    double s = 0.0;
    for (std::size_t i = 0; i < n; ++i)
      s += glm::dot(u[i], v[i]);
    return s;
  };
  // q = P^T A P p, zero on the fixed nodes (p's hanging entries are zero on the way in).
  const auto apply = [&](std::vector<glm::dvec3>& p, std::vector<glm::dvec3>& q) {
    expand(p, hanging);
    multiply(p, q);
    restrict_to_masters(q, hanging);
    for (const HangingNode& h : hanging)
      p[h.node] = glm::dvec3(0.0);
    for (std::size_t i = 0; i < n; ++i)
      if (fixed[i]) q[i] = glm::dvec3(0.0);
  };
  for (std::size_t i = 0; i < n; ++i)
    inv_diag_[i] = glm::dmat3(block(diagonal_[i]));
  // The preconditioner's blocks: a master's own, plus its hanging nodes' by their weights
  // squared (the cross terms left out: it only has to be close and positive definite).
  for (const HangingNode& h : hanging) {
    const glm::dmat3 d(block(diagonal_[h.node]));
    for (std::uint32_t m = 0; m < h.masters_count; ++m)
      inv_diag_[h.masters[m]] += (h.weights[m] * h.weights[m]) * d;
  }
  for (std::size_t i = 0; i < n; ++i) {
    const glm::dmat3 d = inv_diag_[i];
    inv_diag_[i] =
        fixed[i] || std::abs(glm::determinant(d)) < 1e-300 ? glm::dmat3(0.0) : glm::inverse(d);
    if (fixed[i]) x[i] = glm::dvec3(0.0);
  }
  // r = P^T b - P^T A P x.
  p_.assign(x.begin(), x.end());
  apply(p_, r_);
  q_.assign(b.begin(), b.end());
  restrict_to_masters(q_, hanging);
  double b_norm = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    r_[i] = fixed[i] ? glm::dvec3(0.0) : q_[i] - r_[i];
    if (!fixed[i]) b_norm += glm::dot(q_[i], q_[i]);
  }
  b_norm = std::sqrt(b_norm);
  SolveStats stats;
  if (b_norm == 0.0) {
    expand(x, hanging);
    return stats;
  }
  for (std::size_t i = 0; i < n; ++i)
    p_[i] = z_[i] = inv_diag_[i] * r_[i];
  double rz = dot(r_, z_);
  for (int it = 0; it < max_iterations; ++it) {
    const double r_norm = std::sqrt(dot(r_, r_));
    stats.iterations = it;
    stats.relative_residual = r_norm / b_norm;
    if (r_norm <= tolerance * b_norm) {
      expand(x, hanging);
      return stats;
    }
    apply(p_, q_);
    const double pq = dot(p_, q_);
    if (!(pq > 0.0)) break;  // not positive definite along p: stop with what there is
    const double alpha = rz / pq;
    for (std::size_t i = 0; i < n; ++i) {
      x[i] += alpha * p_[i];
      r_[i] -= alpha * q_[i];
      z_[i] = inv_diag_[i] * r_[i];
    }
    const double rz_next = dot(r_, z_);
    const double beta = rz_next / rz;
    rz = rz_next;
    for (std::size_t i = 0; i < n; ++i)
      p_[i] = z_[i] + beta * p_[i];
  }
  stats.iterations = max_iterations;
  stats.relative_residual = std::sqrt(dot(r_, r_)) / b_norm;
  expand(x, hanging);
  return stats;
}

}  // namespace bisturi::sim
