// The implicit integrator's solver structure (integrator.h): a body's free system built from
// its springs (rows of neighbour entries, spring sets), updated around a cut, its aggregates and
// the coarse level's Cholesky factor. The step itself is in integrator.cpp.

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "bisturi/sim/errors.h"
#include "cg_solver.h"
#include "integrator_state.h"

namespace bisturi::sim {
namespace {

constexpr std::uint32_t kNotFree = std::numeric_limits<std::uint32_t>::max();
constexpr std::size_t kMaxStructures = 16;

/// System ids: every build of every integrator's systems gets a new one.
std::atomic<std::uint64_t> next_system_id{1};
constexpr double kNoClass = std::numeric_limits<double>::quiet_NaN();

/// Resizes v to n; a growing array gets room for more (a cut adds vertices and springs, and a
/// copy into fresh pages is slow on this project's VM). The contents are to be rewritten.
template <class T>
void resize_for_growth(std::vector<T>& v, std::size_t n) {
  if (n > v.capacity()) {
    v.clear();
    v.reserve(n + n / 8);
  }
  v.resize(n);
}

/// v = n copies of value, with resize_for_growth's room.
template <class T>
void assign_for_growth(std::vector<T>& v, std::size_t n, const T& value) {
  resize_for_growth(v, n);
  std::fill(v.begin(), v.end(), value);
}

/// A spring set of `count` springs, padded with null springs (vertex 0 to itself) to a
/// multiple of 4; the springs are to be written.
template <class SpringSet>
void reset_spring_set(SpringSet& set, std::size_t count) {
  const std::size_t padded = (count + 3) / 4 * 4;
  set.count = count;
  for (auto* ends : {&set.a, &set.b}) {
    resize_for_growth(*ends, padded);
    std::fill(ends->begin() + static_cast<std::ptrdiff_t>(count), ends->end(), 0u);
  }
  for (auto* values : {&set.rest, &set.k}) {
    resize_for_growth(*values, padded);
    std::fill(values->begin() + static_cast<std::ptrdiff_t>(count), values->end(), 0.0);
  }
}

/// The rows' offsets (prow, nf + 1) from their counts per class (4 per row), each row padded to
/// an even length, and per row and class the first entry to fill.
void row_offsets(const std::uint32_t* free_count, std::size_t nf, std::uint32_t* prow,
                 std::uint32_t* fill) {
  prow[0] = 0;
  for (std::size_t i = 0; i < nf; ++i) {
    std::uint32_t at = prow[i];
    for (std::size_t k = 0; k < 4; ++k) {
      fill[4 * i + k] = at;
      at += free_count[4 * i + k];
    }
    prow[i + 1] = at + ((at - prow[i]) & 1u);
  }
}

/// The last entry of each row padded to an even length (row_offsets) is the row itself: in_i -
/// in_i adds an exact zero to the product.
void pad_rows(const std::uint32_t* free_count, std::size_t nf, const std::uint32_t* prow,
              std::uint32_t* pcol) {
  for (std::size_t i = 0; i < nf; ++i) {
    const std::uint32_t entries =
        free_count[4 * i] + free_count[4 * i + 1] + free_count[4 * i + 2] + free_count[4 * i + 3];
    if (prow[i + 1] - prow[i] != entries) pcol[prow[i + 1] - 1] = static_cast<std::uint32_t>(i);
  }
}

/// Marks a system as made anew: a new id, and no aggregates, coarse factor or fixed springs'
/// energy yet.
template <class System>
void start_build(System& sys) {
  sys.id = next_system_id.fetch_add(1, std::memory_order_relaxed);
  sys.agg.clear();
  sys.coarse_h = -1.0;
  sys.fixed_energy_valid = false;
}

/// vertex: the vertices with mask[i] = 1 in order; compact: vertex -> row (kNotFree if none).
void number_rows(const std::vector<std::uint8_t>& mask, std::vector<std::uint32_t>& vertex,
                 std::vector<std::uint32_t>& compact) {
  const std::size_t n = mask.size();
  std::size_t nf = 0;
  for (std::size_t i = 0; i < n; ++i)
    nf += mask[i];
  resize_for_growth(vertex, nf);
  resize_for_growth(compact, n);
  std::uint32_t row = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (mask[i]) {
      vertex[row] = static_cast<std::uint32_t>(i);
      compact[i] = row++;
    } else {
      compact[i] = kNotFree;
    }
  }
}

/// The index of stiffness k in `classes` (free slots hold kNoClass, which equals nothing), or
/// 4 when it is none of them; without branches, as the classes of consecutive springs
/// alternate.
std::uint32_t class_of(const double (&classes)[4], double k) {
  const std::uint32_t m0 = k == classes[0], m1 = k == classes[1], m2 = k == classes[2],
                      m3 = k == classes[3];
  return m1 + 2 * m2 + 3 * m3 + 4 * (1 - (m0 | m1 | m2 | m3));
}

/// The class of stiffness k, added to the `count` classes when new (springs come in a few
/// stiffness classes, one per kind, numbered in order of first appearance: the rows store the
/// class).
std::uint32_t find_class(double (&classes)[4], std::uint32_t& count, double k) {
  const std::uint32_t c = class_of(classes, k);
  if (c < 4) [[likely]]
    return c;
  if (std::isnan(k)) throw SimInputError("integrator: a spring stiffness is NaN");
  if (count == 4) throw SimInputError("integrator: more than four spring stiffnesses");
  classes[count] = k;
  return count++;
}

}  // namespace

ImplicitEulerState::Structure& ImplicitEulerState::structure(const SoftBody& body) {
  const std::uint64_t generation = body.derived_generation();
  for (Structure& s : structures_) {
    if (s.generation == generation) {
      s.springs = &body.springs();
      return s;
    }
  }
  Structure st;
  // After a cut the body's previous structure is dead: its storage is reused, because fresh pages
  // cost about 2 ms of a 5 cm cut at 20k vertices on this project's VM (page faults, zeroing).
  const auto previous =
      std::find_if(structures_.begin(), structures_.end(),
                   [&](const Structure& s) { return s.lineage == body.lineage(); });
  if (previous != structures_.end()) {
    st = std::move(*previous);
    structures_.erase(previous);
    // A local refresh from the generation the free system was built for changed the springs of
    // a few vertices: the system is updated around them (update_system).
    const SoftBody::SpringChange& change = body.last_spring_change();
    st.local_change = change.from_generation == st.generation && !st.full.prow.empty();
    if (st.local_change) st.changed_vertices = change.vertices;
    st.old_mask.swap(st.free_mask);
    st.free_mask.clear();  // the free system is rebuilt for the new springs
    st.part_dirty = true;
    st.ahead.valid = false;
  } else if (structures_.size() >= kMaxStructures) {
    structures_.erase(structures_.begin());
  }
  if (body.positions().size() > kIndexMask) {
    throw SimInputError("integrator: more than 2^30 vertex slots");
  }
  st.generation = generation;
  st.lineage = body.lineage();
  st.springs = &body.springs();
  structures_.push_back(std::move(st));
  return structures_.back();
}

void ImplicitEulerState::update_free_rows(Structure& st, const std::vector<std::uint8_t>& mask,
                                          const std::vector<double>& masses) {
  if (st.free_mask == mask && !st.full.prow.empty()) return;
  if (st.local_change && update_system(st, st.full, mask)) {
    ++systems_updated_;
  } else {
    build_system(st, st.full, mask);
  }
  st.local_change = false;
  st.free_mask = mask;  // after the build, which throws on bad springs
  aggregate(st.full);
  // The aggregates' rows, for sleeping whole aggregates.
  const std::size_t nf = st.full.vertex.size();
  const std::size_t nc = st.full.coarse_count;
  st.agg_start.assign(nc + 1, 0);
  for (std::size_t i = 0; i < nf; ++i)
    ++st.agg_start[st.full.agg[i] + 1];
  for (std::size_t c = 0; c < nc; ++c)
    st.agg_start[c + 1] += st.agg_start[c];
  resize_for_growth(st.agg_rows, nf);
  std::vector<std::uint32_t> fill(st.agg_start.begin(), st.agg_start.end() - 1);
  for (std::size_t i = 0; i < nf; ++i)
    st.agg_rows[fill[st.full.agg[i]]++] = static_cast<std::uint32_t>(i);
  st.agg_mass2.assign(nc, 0.0);
  for (std::size_t i = 0; i < nf; ++i) {
    const double mi = masses[st.full.vertex[i]];
    st.agg_mass2[st.full.agg[i]] += mi * mi;
  }
  for (auto* v : {&st.sleep_p6, &st.sleep_residual, &st.sleep_gradient, &st.step_residual,
                  &st.step_speed, &st.step_gradient})
    v->assign(nc, 0.0);
  st.awake.assign(nc, 1);
  st.quiet.assign(nc, 0);
  st.asleep = 0;
  st.part_dirty = true;
}

void ImplicitEulerState::build_over_aggregates(Structure& st, System& sys,
                                               const std::vector<std::uint8_t>& flags) {
  const System& full = st.full;
  const std::size_t nc = full.coarse_count;
  mask_.assign(st.free_mask.size(), 0);
  std::vector<std::uint32_t> remap(nc, kNotFree);
  std::uint32_t count = 0;
  for (std::size_t a = 0; a < nc; ++a) {
    if (!flags[a]) continue;
    remap[a] = count++;
    for (std::uint32_t e = st.agg_start[a]; e < st.agg_start[a + 1]; ++e)
      mask_[full.vertex[st.agg_rows[e]]] = 1;
  }
  build_system(st, sys, mask_);
  sys.agg.resize(sys.vertex.size());
  for (std::size_t r = 0; r < sys.vertex.size(); ++r)
    sys.agg[r] = remap[full.agg[full.compact[sys.vertex[r]]]];
  sys.coarse_count = count;
}

void ImplicitEulerState::build_system(Structure& st, System& sys,
                                      const std::vector<std::uint8_t>& mask) {
  start_build(sys);
  number_rows(mask, sys.vertex, sys.compact);
  const std::size_t nf = sys.vertex.size();
  const std::vector<Spring>& springs = *st.springs;
  // The product's form: one run per row, each entry a neighbour with its stiffness class in the
  // top two bits (the product weighs each difference by its class), grouped by class and in
  // spring order within a class, padded to an even length with the row itself (in_i - in_i adds
  // an exact zero), so the product takes two neighbours per trip with one loop exit per row.
  // Springs to constrained vertices only count towards the row's diagonal (fixed_count).
  assign_for_growth(sys.free_count, 4 * nf, 0u);
  assign_for_growth(sys.fixed_count, 4 * nf, 0u);
  double classes[4];
  const std::size_t active = count_entries(springs, sys, classes);
  const std::uint32_t* free_count = sys.free_count.data();
  resize_for_growth(sys.fill, 4 * nf);
  resize_for_growth(sys.prow, nf + 1);
  std::uint32_t* fill = sys.fill.data();  // per row and class: the next entry to fill
  std::uint32_t* prow = sys.prow.data();
  row_offsets(free_count, nf, prow, fill);
  reset_spring_set(sys.active, active);
  reset_spring_set(sys.fixed, springs.size() - active);
  resize_for_growth(sys.pcol, prow[nf]);
  fill_entries<true>(springs, sys, classes, nullptr);
  // Unused classes weigh 0 (they have no entries).
  for (std::size_t k = 0; k < 4; ++k)
    st.k_class[k] = std::isnan(classes[k]) ? 0.0 : classes[k];
  pad_rows(free_count, nf, prow, sys.pcol.data());
  map_entries(st, sys);
}

bool ImplicitEulerState::update_system(Structure& st, System& sys,
                                       const std::vector<std::uint8_t>& mask) {
  const std::vector<std::uint8_t>& old_mask = st.old_mask;
  const std::size_t n_old = old_mask.size(), n = mask.size();
  if (n < n_old || !std::equal(old_mask.begin(), old_mask.end(), mask.begin())) return false;
  const std::vector<Spring>& springs = *st.springs;
  // The classes, numbered by first appearance: the same numbering as before, or a full build.
  double classes[4];
  std::uint32_t used = 0;
  for (std::size_t k = 0; k < 4; ++k) {
    classes[k] = st.k_class[k] > 0.0 ? st.k_class[k] : kNoClass;
    used += st.k_class[k] > 0.0 ? 1 : 0;
  }
  {
    double seen[4] = {kNoClass, kNoClass, kNoClass, kNoClass};
    std::uint32_t count = 0;
    for (std::size_t s = 0; s < springs.size() && count < used; ++s) {
      const double k = springs[s].k_N_per_m;
      if (class_of(seen, k) < 4) continue;
      if (count == 4 || !(k == classes[count])) return false;
      seen[count++] = k;
    }
    if (count != used) return false;
  }
  // Rows: the old ones keep their numbers (their vertices' constraints did not change), the new
  // vertices' rows come after them.
  const std::size_t nf_old = sys.vertex.size();
  sys.compact.resize(n, kNotFree);
  for (std::size_t i = n_old; i < n; ++i) {
    if (!mask[i]) continue;
    sys.compact[i] = static_cast<std::uint32_t>(sys.vertex.size());
    sys.vertex.push_back(static_cast<std::uint32_t>(i));
  }
  const std::size_t nf = sys.vertex.size();
  // Dirty: the changed vertices and the new ones; only their rows are made again.
  std::vector<std::uint8_t>& dirty = st.dirty;
  dirty.assign(n, 0);
  for (const std::uint32_t v : st.changed_vertices)
    if (v < n) dirty[v] = 1;
  for (std::size_t i = n_old; i < n; ++i)
    dirty[i] = 1;
  const std::uint32_t* compact = sys.compact.data();
  sys.free_count.resize(4 * nf, 0);
  sys.fixed_count.resize(4 * nf, 0);
  std::uint32_t* free = sys.free_count.data();
  std::uint32_t* fixed = sys.fixed_count.data();
  for (std::size_t i = 0; i < nf; ++i) {
    if (!dirty[sys.vertex[i]]) continue;
    std::fill(free + 4 * i, free + 4 * i + 4, 0u);
    std::fill(fixed + 4 * i, fixed + 4 * i + 4, 0u);
  }
  // The dirty rows' counts, from the springs with a dirty end (as count_entries).
  std::size_t active = 0;
  for (const Spring& sp : springs) {
    const std::uint32_t ca = compact[sp.a], cb = compact[sp.b];
    active += (ca != kNotFree || cb != kNotFree) ? 1 : 0;
    if (!dirty[sp.a] && !dirty[sp.b]) continue;
    const std::uint32_t cls = class_of(classes, sp.k_N_per_m);
    if (cls == 4) return false;  // a new stiffness: build_system makes everything again
    if (ca != kNotFree && dirty[sp.a]) ++(cb != kNotFree ? free : fixed)[4 * ca + cls];
    if (cb != kNotFree && dirty[sp.b]) ++(ca != kNotFree ? free : fixed)[4 * cb + cls];
  }
  // The new row offsets; the old ones are kept to copy the clean rows from.
  sys.prow_old.swap(sys.prow);
  sys.pcol_old.swap(sys.pcol);
  const std::uint32_t* prow_old = sys.prow_old.data();
  const std::uint32_t* pcol_old = sys.pcol_old.data();
  resize_for_growth(sys.prow, nf + 1);
  resize_for_growth(sys.fill, 4 * nf);
  std::uint32_t* prow = sys.prow.data();
  std::uint32_t* fill = sys.fill.data();
  row_offsets(free, nf, prow, fill);
  resize_for_growth(sys.pcol, prow[nf]);
  std::uint32_t* pcol = sys.pcol.data();
  for (std::size_t i = 0; i < nf_old; ++i) {
    if (dirty[sys.vertex[i]]) continue;
    std::copy(pcol_old + prow_old[i], pcol_old + prow_old[i + 1], pcol + prow[i]);
  }
  // The spring sets in full, and the dirty rows' entries (in spring order, as fill_entries).
  reset_spring_set(sys.active, active);
  reset_spring_set(sys.fixed, springs.size() - active);
  fill_entries<false>(springs, sys, classes, dirty.data());
  pad_rows(free, nf, prow, pcol);
  map_entries(st, sys);
  start_build(sys);
  return true;
}

std::string ImplicitEulerState::check_free_system(const SoftBody& body) {
  const auto held = std::find_if(structures_.begin(), structures_.end(), [&](const Structure& s) {
    return s.generation == body.derived_generation();
  });
  if (held == structures_.end()) return "no structure for the body's generation";
  const Structure& st = *held;
  if (st.full.prow.empty()) return "no free system yet";
  Structure fresh;
  fresh.springs = &body.springs();
  build_system(fresh, fresh.full, st.free_mask);
  const System &a = st.full, &b = fresh.full;
  auto same = [](const auto& x, const auto& y) { return x.size() == y.size() && x == y; };
  if (!std::equal(std::begin(st.k_class), std::end(st.k_class), std::begin(fresh.k_class)))
    return "stiffness classes";
  if (!same(a.vertex, b.vertex) || !same(a.compact, b.compact)) return "row numbering";
  if (!same(a.free_count, b.free_count) || !same(a.fixed_count, b.fixed_count)) return "row counts";
  if (!same(a.prow, b.prow)) return "row offsets";
  if (!same(a.pcol, b.pcol)) return "row entries";
  auto same_set = [&](const System::SpringSet& x, const System::SpringSet& y) {
    return x.count == y.count && same(x.a, y.a) && same(x.b, y.b) && same(x.rest, y.rest) &&
           same(x.k, y.k);
  };
  if (!same_set(a.active, b.active)) return "active springs";
  if (!same_set(a.fixed, b.fixed)) return "fixed springs";
  if (!same(a.entry_spring, b.entry_spring) || !same(a.held_springs, b.held_springs))
    return "entry springs";
  return {};
}

std::size_t ImplicitEulerState::count_entries(const std::vector<Spring>& springs, System& sys,
                                              double (&classes)[4]) {
  std::fill(std::begin(classes), std::end(classes), kNoClass);
  std::uint32_t count = 0;
  const std::uint32_t* compact = sys.compact.data();
  std::uint32_t* free = sys.free_count.data();
  std::uint32_t* fixed = sys.fixed_count.data();
  std::size_t active = 0;
  for (const Spring& sp : springs) {
    const std::uint32_t ca = compact[sp.a], cb = compact[sp.b];
    const std::uint32_t cls = find_class(classes, count, sp.k_N_per_m);
    if (ca != kNotFree && cb != kNotFree) {
      ++free[4 * ca + cls];
      ++free[4 * cb + cls];
    } else if (ca != kNotFree) {
      ++fixed[4 * ca + cls];
    } else if (cb != kNotFree) {
      ++fixed[4 * cb + cls];
    }
    active += (ca != kNotFree || cb != kNotFree) ? 1 : 0;
  }
  return active;
}

template <bool AllRows>
void ImplicitEulerState::fill_entries(const std::vector<Spring>& springs, System& sys,
                                      const double (&classes)[4], const std::uint8_t* dirty) {
  // The two spring sets in spring order (those with a solved end and the others), and each
  // spring between solved vertices as an entry in both its rows.
  const std::uint32_t* compact = sys.compact.data();
  std::uint32_t* fill = sys.fill.data();
  std::uint32_t* pcol = sys.pcol.data();
  std::uint32_t *active_a = sys.active.a.data(), *active_b = sys.active.b.data();
  double *active_rest = sys.active.rest.data(), *active_k = sys.active.k.data();
  std::uint32_t *fixed_a = sys.fixed.a.data(), *fixed_b = sys.fixed.b.data();
  double *fixed_rest = sys.fixed.rest.data(), *fixed_k = sys.fixed.k.data();
  for (const Spring& sp : springs) {
    const std::uint32_t ca = compact[sp.a], cb = compact[sp.b];
    if (ca == kNotFree && cb == kNotFree) {
      *fixed_a++ = sp.a;
      *fixed_b++ = sp.b;
      *fixed_rest++ = sp.rest_m;
      *fixed_k++ = sp.k_N_per_m;
      continue;
    }
    *active_a++ = sp.a;
    *active_b++ = sp.b;
    *active_rest++ = sp.rest_m;
    *active_k++ = sp.k_N_per_m;
    if (ca == kNotFree || cb == kNotFree) continue;
    if constexpr (AllRows) {
      const std::uint32_t cls = class_of(classes, sp.k_N_per_m);
      pcol[fill[4 * ca + cls]++] = cb | (cls << 30);
      pcol[fill[4 * cb + cls]++] = ca | (cls << 30);
    } else {
      // Only the rows of dirty vertices (update_system copies the others).
      if (!dirty[sp.a] && !dirty[sp.b]) continue;
      const std::uint32_t cls = class_of(classes, sp.k_N_per_m);
      if (dirty[sp.a]) pcol[fill[4 * ca + cls]++] = cb | (cls << 30);
      if (dirty[sp.b]) pcol[fill[4 * cb + cls]++] = ca | (cls << 30);
    }
  }
}

void ImplicitEulerState::map_entries(const Structure& st, System& sys) {
  // The entries of a row are grouped by class and in spring order within a class (fill_entries,
  // update_system): walking the active springs in order with a cursor per row and class meets
  // them in the same order. Each entry is checked against its neighbour; a row that does not
  // match (which the build's order rules out) is searched instead.
  const std::size_t nf = sys.vertex.size();
  const std::uint32_t* prow = sys.prow.data();
  const std::uint32_t* pcol = sys.pcol.data();
  const std::uint32_t* free_count = sys.free_count.data();
  const std::uint32_t* compact = sys.compact.data();
  const std::size_t entries = nf > 0 ? prow[nf] : 0;
  assign_for_growth(sys.entry_spring, entries, kNotFree);
  sys.held_springs.clear();
  resize_for_growth(sys.fill, 4 * nf);
  std::uint32_t* fill = sys.fill.data();
  for (std::size_t i = 0; i < nf; ++i) {
    std::uint32_t at = prow[i];
    for (std::size_t k = 0; k < 4; ++k) {
      fill[4 * i + k] = at;
      at += free_count[4 * i + k];
    }
  }
  double classes[4];
  for (std::size_t k = 0; k < 4; ++k)
    classes[k] = st.k_class[k] > 0.0 ? st.k_class[k] : kNoClass;
  std::uint32_t* spring = sys.entry_spring.data();
  const System::SpringSet& sa = sys.active;
  // The first entry of row r not yet taken whose neighbour is c (the search's fallback).
  auto search = [&](std::uint32_t r, std::uint32_t c) {
    for (std::uint32_t e = prow[r]; e < prow[r + 1]; ++e)
      if ((pcol[e] & kIndexMask) == c && spring[e] == kNotFree) return e;
    return kNotFree;
  };
  for (std::size_t s = 0; s < sa.count; ++s) {
    const std::uint32_t ca = compact[sa.a[s]], cb = compact[sa.b[s]];
    if (ca == kNotFree || cb == kNotFree) {
      sys.held_springs.push_back(ca != kNotFree ? ca : cb);
      sys.held_springs.push_back(static_cast<std::uint32_t>(s));
      continue;
    }
    const std::uint32_t cls = class_of(classes, sa.k[s]);
    for (const auto& [row, other] : {std::pair{ca, cb}, std::pair{cb, ca}}) {
      std::uint32_t e = cls < 4 ? fill[4 * row + cls]++ : kNotFree;
      if (e == kNotFree || e >= prow[row + 1] || (pcol[e] & kIndexMask) != other ||
          spring[e] != kNotFree)
        e = search(row, other);
      if (e != kNotFree) spring[e] = static_cast<std::uint32_t>(s);
    }
  }
}

void ImplicitEulerState::aggregate(System& sys) {
  const std::size_t nf = sys.vertex.size();
  const std::uint32_t* row = sys.prow.data();
  const std::uint32_t* col = sys.pcol.data();
  // A row's neighbours (and the row itself as padding, which is assigned or the row in hand
  // wherever it is met below).
  auto neighbour = [col](std::uint32_t e) { return col[e] & kIndexMask; };
  // Aggregates: a seed whose neighbours are all unassigned takes them and grows by whole rings
  // of neighbours until it holds `target` rows; leftovers join an assigned neighbour's
  // aggregate. About nf / 192 aggregates (the coarse solve stays below a fifth of a
  // product at 20k vertices), but no more than 80 rows each: at 95k vertices aggregates of
  // 330 rows left a relative residual of 0.65 after 6 iterations, of 80 rows 0.02.
  const std::size_t target = std::clamp<std::size_t>(nf / 192, 8, 80);
  constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
  assign_for_growth(sys.agg, nf, kNone);
  std::uint32_t* agg = sys.agg.data();  // in a local: the stores below do not reload it
  std::uint32_t count = 0;
  std::vector<std::uint32_t> ring, next;
  for (std::size_t seed = 0; seed < nf; ++seed) {
    if (agg[seed] != kNone) continue;
    // Without branches per neighbour (whether one is taken is a coin toss at the aggregates'
    // borders): every neighbour is looked at, and a ring's members are packed.
    bool taken_around = false;
    for (std::uint32_t e = row[seed]; e < row[seed + 1]; ++e)
      taken_around |= agg[neighbour(e)] != kNone;
    if (taken_around) continue;
    agg[seed] = count;
    std::size_t size = 1;
    ring.assign(1, static_cast<std::uint32_t>(seed));
    while (size < target && !ring.empty()) {
      std::size_t room = 0;
      for (std::uint32_t i : ring)
        room += row[i + 1] - row[i];
      next.resize(room);
      std::size_t got = 0;
      for (std::uint32_t i : ring) {
        for (std::uint32_t e = row[i]; e < row[i + 1]; ++e) {
          const std::uint32_t j = neighbour(e);
          const bool fresh = agg[j] == kNone;
          agg[j] = fresh ? count : agg[j];
          next[got] = j;
          got += fresh ? 1 : 0;
        }
      }
      next.resize(got);
      size += got;
      ring.swap(next);
    }
    ++count;
  }
  for (bool changed = true; changed;) {
    changed = false;
    for (std::size_t i = 0; i < nf; ++i) {
      if (agg[i] != kNone) continue;
      for (std::uint32_t e = row[i]; e < row[i + 1]; ++e) {
        if (agg[neighbour(e)] != kNone) {
          agg[i] = agg[neighbour(e)];
          changed = true;
          break;
        }
      }
    }
  }
  for (std::size_t i = 0; i < nf; ++i) {  // rows with no free neighbour at all
    if (agg[i] == kNone) agg[i] = count++;
  }
  sys.coarse_count = count;
}

void ImplicitEulerState::update_coarse(System& sys, const Structure& st, const SoftBody& body,
                                       double h) {
  if (sys.coarse_h == h) return;
  const std::size_t nc = sys.coarse_count;
  const Material& mat = body.material();
  double w[4];
  for (int k = 0; k < 4; ++k)
    w[k] = h * h * st.k_class[k] + h * mat.spring_damping_N_s_per_m;
  collect_coarse(sys, body, w, h);
  // Cholesky of P^T A P in skyline form: row I holds columns first[I]..I (its envelope: the
  // factor fills nothing left of a row's first nonzero), 1 / L_II last. Aggregates are numbered
  // along the vertex order, so the envelope is narrow: 4.4k entries against 20.7k dense for the
  // 19.4k sphere's 203 aggregates. Each row of P^T A P is assembled from its links just before
  // it is factored, into a scratch row cleared again after: no nc x nc matrix (its zeroing and
  // fresh pages cost more than the factor).
  assign_for_growth(sys.coarse_row, nc, 0.0);
  resize_for_growth(sys.coarse_first, nc);
  resize_for_growth(sys.coarse_start, nc + 1);
  sys.coarse_start[0] = 0;
  sys.coarse.clear();
  for (std::size_t i = 0; i < nc; ++i) {
    const std::size_t lowest = assemble_coarse_row(sys, w, i);
    std::size_t first = lowest;  // the first nonzero (sums of weights can be exact zeros)
    while (first < i && sys.coarse_row[first] == 0.0)
      ++first;
    sys.coarse_first[i] = static_cast<std::uint32_t>(first);
    sys.coarse_start[i + 1] = sys.coarse_start[i] + static_cast<std::uint32_t>(i - first + 1);
    sys.coarse.resize(sys.coarse_start[i + 1]);
    factor_coarse_row(sys, i, first);
    std::fill(sys.coarse_row.begin() + static_cast<std::ptrdiff_t>(lowest),
              sys.coarse_row.begin() + static_cast<std::ptrdiff_t>(i), 0.0);
  }
  sys.coarse_f.resize(sys.coarse.size());
  for (std::size_t i = 0; i < sys.coarse.size(); ++i)
    sys.coarse_f[i] = static_cast<float>(sys.coarse[i]);
  sys.coarse_h = h;
}

void ImplicitEulerState::collect_coarse(System& sys, const SoftBody& body, const double (&w)[4],
                                        double h) {
  // P^T A P with P the aggregates' indicator: an aggregate sums its rows' diagonal parts that
  // are not a free neighbour's weight, and the weights of springs leaving it. The rows are taken
  // in order (a pass in aggregate order waits on memory at every row), each aggregate's sums in
  // the order of the dense assembly this replaced, bit for bit.
  const std::size_t nf = sys.vertex.size();
  const std::size_t nc = sys.coarse_count;
  const std::uint32_t* prow = sys.prow.data();
  const std::uint32_t* col = sys.pcol.data();
  const std::uint32_t* agg = sys.agg.data();
  const std::uint32_t* fixed = sys.fixed_count.data();
  const double* m = body.masses().data();
  const double inertia = 1.0 + h * body.material().drag_per_s;
  assign_for_growth(sys.coarse_diag, nc, 0.0);
  assign_for_growth(sys.link_start, nc + 1, 0u);
  double* diag = sys.coarse_diag.data();
  std::uint32_t* start = sys.link_start.data();
  // A row's entries to other aggregates are packed without branches first (a fifth of the
  // entries, strewn: a branch per entry mispredicted at each), then summed in order.
  std::size_t longest = 0;
  for (std::size_t i = 0; i < nf; ++i)
    longest = std::max<std::size_t>(longest, prow[i + 1] - prow[i]);
  resize_for_growth(sys.links, longest);
  std::uint32_t* cross = sys.links.data();               // aggregate J | class << 30
  std::vector<std::uint32_t>& pairs = sys.link_scratch;  // (aggregate, link) in row order
  pairs.clear();
  for (std::size_t i = 0; i < nf; ++i) {
    const std::uint32_t I = agg[i];
    std::size_t n = 0;
    for (std::uint32_t e = prow[i]; e < prow[i + 1]; ++e) {
      const std::uint32_t J = agg[col[e] & kIndexMask];
      cross[n] = J | (col[e] & ~kIndexMask);
      n += J != I ? 1 : 0;  // the row's own padding is never packed
    }
    double self = m[sys.vertex[i]] * inertia;
    for (std::size_t k = 0; k < 4; ++k)
      self += double(fixed[4 * i + k]) * w[k];
    double d = diag[I];
    for (std::size_t c = 0; c < n; ++c)
      d += w[cross[c] >> 30];
    diag[I] = d + self;
    // The links left of the diagonal (the factor reads the lower triangle only).
    const std::size_t at = pairs.size();
    pairs.resize(at + 2 * n);
    std::uint32_t* out = pairs.data() + at;
    std::size_t kept = 0;
    for (std::size_t c = 0; c < n; ++c) {
      out[kept] = I;
      out[kept + 1] = cross[c];
      kept += (cross[c] & kIndexMask) < I ? 2 : 0;
    }
    pairs.resize(at + kept);
    start[I + 1] += static_cast<std::uint32_t>(kept / 2);
  }
  for (std::size_t c = 0; c < nc; ++c)
    start[c + 1] += start[c];
  resize_for_growth(sys.links, pairs.size() / 2);
  for (std::size_t p = 0; p < pairs.size(); p += 2)
    sys.links[start[pairs[p]]++] = pairs[p + 1];
  // The scatter moved each start to the next aggregate's: back by one.
  for (std::size_t c = nc; c > 0; --c)
    start[c] = start[c - 1];
  start[0] = 0;
}

std::size_t ImplicitEulerState::assemble_coarse_row(System& sys, const double (&w)[4],
                                                    std::size_t row) {
  double* out = sys.coarse_row.data();
  std::size_t lowest = row;
  for (std::uint32_t l = sys.link_start[row]; l < sys.link_start[row + 1]; ++l) {
    const std::uint32_t J = sys.links[l] & kIndexMask;
    out[J] -= w[sys.links[l] >> 30];
    lowest = std::min<std::size_t>(lowest, J);
  }
  return lowest;
}

void ImplicitEulerState::factor_coarse_row(System& sys, std::size_t row, std::size_t first) {
  double* L = sys.coarse.data();
  const std::uint32_t* row_first = sys.coarse_first.data();
  const std::uint32_t* row_start = sys.coarse_start.data();
  // factor_row(i)[k] is L_ik for k in [first[i], i].
  auto factor_row = [&](std::size_t i) { return L + row_start[i] - row_first[i]; };
  const double* a = sys.coarse_row.data();
  double* li = factor_row(row);
  for (std::size_t j = first; j <= row; ++j) {
    double sum = j < row ? a[j] : sys.coarse_diag[row];
    const double* lj = factor_row(j);
    for (std::size_t k = std::max<std::size_t>(first, row_first[j]); k < j; ++k)
      sum -= li[k] * lj[k];
    if (j < row) {
      li[j] = sum * lj[j];
    } else {
      li[row] = sum > 0.0 ? 1.0 / std::sqrt(sum) : 0.0;  // SPD; 0 drops a bad aggregate
    }
  }
}

}  // namespace bisturi::sim
