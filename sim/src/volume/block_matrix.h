#pragma once
// A symmetric matrix of 3 x 3 blocks with the sparsity of a hexahedral lattice (node i and j
// coupled when they share a cell), and a conjugate-gradient solve preconditioned by its inverted
// diagonal blocks. Nodes marked fixed are held: the solve leaves their entries zero. The blocks
// are single precision (the products stream the matrix: half the bytes, and a solve to a
// relative residual of 1e-3 or 1e-4 needs no more); vectors and sums are double.

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include <glm/mat3x3.hpp>
#include <glm/vec3.hpp>

#include "bisturi/sim/volume/hex_lattice.h"

namespace bisturi::sim {

class BlockMatrix {
 public:
  /// The pattern of `nodes` nodes coupled by `cells` (8 nodes each).
  BlockMatrix(std::size_t nodes, std::span<const std::array<std::uint32_t, 8>> cells);

  void set_zero();
  /// Cell c's 64 slots, [a * 8 + b] for its corners a and b.
  [[nodiscard]] const std::array<std::uint32_t, 64>& cell_slots(std::size_t c) const {
    return cell_slots_[c];
  }
  /// Adds m to the block in `slot`.
  void add(std::uint32_t slot, const glm::mat3& m) {
    float* b = values_[slot].data();
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r)
        b[4 * c + r] += m[c][r];
  }
  [[nodiscard]] glm::mat3 block(std::uint32_t slot) const;
  /// The slot of node i's own block.
  [[nodiscard]] std::uint32_t diagonal_slot(std::size_t i) const { return diagonal_[i]; }
  [[nodiscard]] std::size_t nodes() const { return row_start_.size() - 1; }

  /// y = A x.
  void multiply(std::span<const glm::dvec3> x, std::span<glm::dvec3> y) const;

  struct SolveStats {
    int iterations = 0;
    double relative_residual = 0.0;
  };
  /// Solves A x = b over the nodes not fixed (x starts from its given value; fixed entries of
  /// x are set to zero) until |r| <= tolerance |b| or max_iterations. With hanging nodes, over
  /// the free nodes only: x = P y for the y solving P^T A P y = P^T b, P giving each hanging
  /// node its masters' weighted sum (x comes back whole, its hanging entries so given).
  SolveStats solve(std::span<const glm::dvec3> b, std::span<glm::dvec3> x,
                   std::span<const std::uint8_t> fixed, double tolerance, int max_iterations,
                   std::span<const HangingNode> hanging = {});
  /// x's hanging entries set to their masters' weighted sum (P y).
  static void expand(std::span<glm::dvec3> x, std::span<const HangingNode> hanging);
  /// Each hanging entry of v moved onto its masters by its weights, and zeroed (P^T v).
  static void restrict_to_masters(std::span<glm::dvec3> v, std::span<const HangingNode> hanging);

 private:
  std::vector<std::uint32_t> row_start_;  ///< CSR over nodes
  std::vector<std::uint32_t> columns_;
  std::vector<std::uint32_t> diagonal_;  ///< each row's own block
  /// Each block's columns, each padded to 4 floats: a product's column is one 4-wide vector.
  std::vector<std::array<float, 12>> values_;
  std::vector<std::array<std::uint32_t, 64>> cell_slots_;
  std::vector<glm::dvec3> r_, z_, p_, q_;      // solver scratch
  std::vector<std::uint8_t> held_or_hanging_;  // solver scratch
  std::vector<glm::dmat3> inv_diag_;
  /// multiply()'s operand in single precision, padded to 4 floats.
  mutable std::vector<std::array<float, 4>> x_single_;
};

}  // namespace bisturi::sim
