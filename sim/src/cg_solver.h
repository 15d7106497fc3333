#pragma once
// The conjugate gradient of the implicit step (integrator.cpp builds its data): 3 x 3 spring
// blocks between neighbours (a I + s s^T each) plus a diagonal, held springs' and contact blocks,
// four lanes (x, y, z, zero pad) per free vertex, Jacobi plus an optional coarse level (aggregates,
// packed Cholesky factor), optionally split over the step's thread team.

#include <cstddef>
#include <cstdint>

#include "step_threads.h"

namespace bisturi::sim {

/// Neighbour entries of the rows: the index in the low 30 bits, the stiffness class above.
constexpr std::uint32_t kIndexMask = (1u << 30) - 1u;

/// The CG's data, four lanes (x, y, z, zero pad) per free vertex.
template <class T>
struct CgData {
  std::size_t nf = 0;
  const std::uint32_t* row = nullptr;  ///< nf + 1 offsets into col
  const std::uint32_t* col = nullptr;  ///< neighbour | class << 30, even count per row
  const T* self = nullptr;             ///< per row: its mass part of the diagonal
  /// Per entry of col: the spring's block a I + s s^T as (s.x, s.y, s.z, a); zero for padding.
  const float* blk = nullptr;
  /// 5 per spring from a row to a held vertex: row, s.x, s.y, s.z, a (a diagonal block).
  const double* held_blocks = nullptr;
  std::size_t held = 0;
  /// Block Jacobi: per row the inverse of its 3 x 3 diagonal block (contacts included) as three
  /// 4-lane rows with zero pads (12 per row).
  const T* inv = nullptr;
  const T* b = nullptr;             ///< right-hand side
  const double* contact = nullptr;  ///< 5 per contact: compact index, nx, ny, nz, k
  std::size_t contacts = 0;
  T *dv = nullptr, *r = nullptr, *p = nullptr, *ap = nullptr;
  // Coarse level (nc = 0: Jacobi alone): row -> aggregate, the Cholesky factor in skyline form
  // (row I: columns chol_first[I]..I from chol[chol_start[I]], the diagonal inverted), and two
  // 4-lane vectors of nc aggregates.
  std::size_t nc = 0;
  const std::uint32_t* agg = nullptr;
  const T* chol = nullptr;
  const std::uint32_t* chol_first = nullptr;
  const std::uint32_t* chol_start = nullptr;
  T *rc = nullptr, *xc = nullptr;
  double stop2 = 0.0;  ///< squared residual that ends a solve once it has started
  // Threads (team != nullptr): member t takes rows [part[t], part[t + 1]) of every pass, and
  // members 1.. restrict their rows' residuals into their own coarse vectors (4 nc each).
  StepThreads* team = nullptr;
  const std::uint32_t* part = nullptr;
  T* rc_parts = nullptr;
};

/// Runs the CG from the start value in d.dv; returns the iterations, r2 the last squared
/// residual. It stops once r2 <= tol2 before the first iteration, or r2 <= d.stop2 after one.
int run_cg(const CgData<float>& d, int max_iterations, double tol2, double& r2);
int run_cg(const CgData<double>& d, int max_iterations, double tol2, double& r2);

}  // namespace bisturi::sim
