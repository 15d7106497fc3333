#include "bisturi/sim/integrator.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <type_traits>

#include <glm/geometric.hpp>

#include "bisturi/sim/errors.h"
#include "cg_solver.h"
#include "spring_kernels.h"
#include "step_threads.h"
#include "volume_kernels.h"

namespace bisturi::sim {
namespace {

constexpr std::uint32_t kNotFree = std::numeric_limits<std::uint32_t>::max();
constexpr std::size_t kMaxStructures = 16;
constexpr double kNeverQuiet = std::numeric_limits<double>::infinity();

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

/// The array team member t accumulates into: `first` (zeroed by the caller) for member 0, its
/// own zeroed array of the same size for the others.
glm::dvec3* member_array(std::vector<glm::dvec3>& first,
                         std::vector<std::vector<glm::dvec3>>& others, unsigned t) {
  if (t == 0) return first.data();
  others[t - 1].assign(first.size(), glm::dvec3(0.0));
  return others[t - 1].data();
}

}  // namespace

ImplicitIntegrator::Structure& ImplicitIntegrator::structure(const SoftBody& body) {
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

void ImplicitIntegrator::update_free_rows(Structure& st, const std::vector<std::uint8_t>& mask,
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

void ImplicitIntegrator::build_system(Structure& st, System& sys,
                                      const std::vector<std::uint8_t>& mask) {
  sys.id = next_system_id.fetch_add(1, std::memory_order_relaxed);
  sys.agg.clear();
  sys.coarse_h = -1.0;
  sys.fixed_energy_valid = false;
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
  prow[0] = 0;
  for (std::size_t i = 0; i < nf; ++i) {
    std::uint32_t at = prow[i];
    for (std::size_t k = 0; k < 4; ++k) {
      fill[4 * i + k] = at;
      at += free_count[4 * i + k];
    }
    prow[i + 1] = at + ((at - prow[i]) & 1u);
  }
  // The spring sets padded with null springs (vertex 0 to itself).
  auto reset = [](System::SpringSet& set, std::size_t count) {
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
  };
  reset(sys.active, active);
  reset(sys.fixed, springs.size() - active);
  resize_for_growth(sys.pcol, prow[nf]);
  fill_entries<true>(springs, sys, classes, nullptr);
  // Unused classes weigh 0 (they have no entries).
  for (std::size_t k = 0; k < 4; ++k)
    st.k_class[k] = std::isnan(classes[k]) ? 0.0 : classes[k];
  std::uint32_t* pcol = sys.pcol.data();
  for (std::size_t i = 0; i < nf; ++i) {
    if (fill[4 * i + 3] != prow[i + 1]) pcol[prow[i + 1] - 1] = static_cast<std::uint32_t>(i);
  }
}

bool ImplicitIntegrator::update_system(Structure& st, System& sys,
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
  prow[0] = 0;
  for (std::size_t i = 0; i < nf; ++i) {
    std::uint32_t at = prow[i];
    for (std::size_t k = 0; k < 4; ++k) {
      fill[4 * i + k] = at;
      at += free[4 * i + k];
    }
    prow[i + 1] = at + ((at - prow[i]) & 1u);
  }
  resize_for_growth(sys.pcol, prow[nf]);
  std::uint32_t* pcol = sys.pcol.data();
  for (std::size_t i = 0; i < nf_old; ++i) {
    if (dirty[sys.vertex[i]]) continue;
    std::copy(pcol_old + prow_old[i], pcol_old + prow_old[i + 1], pcol + prow[i]);
  }
  // The spring sets in full, and the dirty rows' entries (in spring order, as fill_entries).
  auto reset = [](System::SpringSet& set, std::size_t count) {
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
  };
  reset(sys.active, active);
  reset(sys.fixed, springs.size() - active);
  fill_entries<false>(springs, sys, classes, dirty.data());
  for (std::size_t i = 0; i < nf; ++i) {
    if (dirty[sys.vertex[i]] && fill[4 * i + 3] != prow[i + 1]) {
      pcol[prow[i + 1] - 1] = static_cast<std::uint32_t>(i);
    }
  }
  sys.id = next_system_id.fetch_add(1, std::memory_order_relaxed);
  sys.agg.clear();
  sys.coarse_h = -1.0;
  sys.fixed_energy_valid = false;
  return true;
}

std::string ImplicitIntegrator::check_free_system(const SoftBody& body) {
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
  return {};
}

std::size_t ImplicitIntegrator::count_entries(const std::vector<Spring>& springs, System& sys,
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
void ImplicitIntegrator::fill_entries(const std::vector<Spring>& springs, System& sys,
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

void ImplicitIntegrator::aggregate(System& sys) {
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

void ImplicitIntegrator::update_coarse(System& sys, const Structure& st, const SoftBody& body,
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

void ImplicitIntegrator::collect_coarse(System& sys, const SoftBody& body, const double (&w)[4],
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

std::size_t ImplicitIntegrator::assemble_coarse_row(System& sys, const double (&w)[4],
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

void ImplicitIntegrator::factor_coarse_row(System& sys, std::size_t row, std::size_t first) {
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

void ImplicitIntegrator::free_mask(const SoftBody& body) {
  const auto& m = body.masses();
  const std::size_t n = m.size();
  free_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const VertexId vi(static_cast<std::uint32_t>(i));
    free_[i] = (m[i] <= 0.0 || body.anchored(vi) || body.kinematic(vi)) ? 0 : 1;
  }
}

void ImplicitIntegrator::prepare(SoftBody& body, const IntegratorOptions& options) {
  body.refresh_topology();
  Structure& st = structure(body);
  free_mask(body);
  update_free_rows(st, free_, body.masses());
  if (options.cg_coarse_level) update_coarse(st.full, st, body, options.dt_s);
  // Scratch at its working size, so the first step allocates nothing.
  const std::size_t n = body.positions().size();
  const std::size_t n4 = 4 * st.full.vertex.size();
  saved_x_.reserve(n);
  saved_v_.reserve(n);
  f_.reserve(n);
  grad_.reserve(n);
  for (auto* vec : {&rhs_, &dv_})
    vec->reserve(n4);
  fbuf_.reserve(4 * n4);
  dbuf_.reserve(3 * n4);
}

StepStats ImplicitIntegrator::step(SoftBody& body, const IntegratorOptions& options,
                                   std::vector<SimEvent>& events, std::uint32_t body_index,
                                   std::uint64_t step_index) {
  StepStats stats;
  step_team_ = team(options);
  body.refresh_topology();
  if (body.frozen()) {
    body.clear_forces();
    stats.frozen = true;
    return stats;
  }
  Structure& st = structure(body);
  if (options.sleeping && sleeps_entirely(st, body)) {
    stats.free_vertices = static_cast<std::uint32_t>(st.full.vertex.size());
    body.clear_forces();
    return stats;
  }
  // Read before the non-const views below count as edits.
  const bool untouched =
      st.ahead.valid && st.ahead.state_edits == body.state_edits() && st.ahead.members == members();
  st.ahead.valid = false;
  auto& x = body.positions();
  auto& v = body.velocities();
  saved_x_ = x;
  saved_v_ = v;
  const auto& masses = body.masses();
  bool any_kinematic = false;
  for (std::size_t i = 0; i < masses.size(); ++i) {
    if (body.kinematic(VertexId(static_cast<std::uint32_t>(i)))) any_kinematic = true;
  }
  const bool energy_check = !any_kinematic;
  double energy_before = 0.0;
  // Kinematic vertices move their neighbours every step: nothing sleeps while there are any.
  if (!options.sleeping || any_kinematic) wake_all(st);

  for (int attempt = 0; attempt <= options.max_retry_halvings; ++attempt) {
    const int substeps = 1 << attempt;
    const double h = options.dt_s / substeps;
    StepStats trial;
    trial.substeps = substeps;
    System* sys = nullptr;
    for (int s = 0; s < substeps; ++s) {
      // The energy of the start state comes out of the first substep's force pass for free.
      const bool first = attempt == 0 && s == 0 && energy_check;
      sys = &substep(body, st, options, h, double(s + 1) / substeps, trial,
                     first ? &energy_before : nullptr, first && untouched);
    }
    const double elastic_after = energy_check ? end_pass(st, *sys, body, options) : 0.0;
    const std::string reason = check(body, options, energy_before, energy_check, elastic_after);
    if (reason.empty()) {
      trial.rolled_back = attempt > 0;
      trial.free_vertices = static_cast<std::uint32_t>(st.full.vertex.size());
      trial.awake_vertices = static_cast<std::uint32_t>(sys->vertex.size());
      if (options.sleeping && !any_kinematic && attempt == 0) update_sleep(st, body, options);
      body.clear_forces();
      // Sleep changes show as a new system id; edits from now on as a new count.
      st.ahead.valid = energy_check;
      st.ahead.state_edits = body.state_edits();
      return trial;
    }
    events.push_back({SimEventKind::RolledBack, body_index, step_index, substeps, reason});
    x = saved_x_;
    v = saved_v_;
    std::fill(body.warm_start().begin(), body.warm_start().end(), glm::dvec3(0.0));
  }
  events.push_back({SimEventKind::Frozen, body_index, step_index, 1 << options.max_retry_halvings,
                    "still diverging with the smallest substep: the solid is frozen"});
  body.freeze();
  stats.frozen = true;
  stats.rolled_back = true;
  return stats;
}

std::string ImplicitIntegrator::check(const SoftBody& body, const IntegratorOptions& options,
                                      double energy_before, bool energy_check,
                                      double elastic_after) const {
  const auto& x = body.positions();
  const auto& v = body.velocities();
  const auto& m = body.masses();
  const auto& fext = body.external_forces();
  const glm::dvec3 g = options.gravity_m_s2;
  const double max_speed2 = options.max_speed_m_s * options.max_speed_m_s;
  // One sweep: the external forces' work over the step, finiteness, the fastest vertex and the
  // kinetic and gravitational energies.
  double work = 0.0, sum = 0.0, fastest = 0.0, kinetic = 0.0, potential = 0.0;
  const std::size_t n = x.size();
  for (std::size_t i = 0; i < n; ++i) {
    const glm::dvec3 xi = x[i], vi = v[i];
    work += glm::dot(fext[i], xi - saved_x_[i]);
    sum += xi.x + xi.y + xi.z + vi.x + vi.y + vi.z;
    const double v2 = glm::dot(vi, vi);
    fastest = std::max(fastest, v2);
    kinetic += 0.5 * m[i] * v2;
    potential -= m[i] * glm::dot(g, xi);
  }
  if (!std::isfinite(work)) return "non-finite external force";
  if (!std::isfinite(sum) || !std::isfinite(fastest)) {
    for (std::size_t i = 0; i < n; ++i) {
      const double s = x[i].x + x[i].y + x[i].z + v[i].x + v[i].y + v[i].z;
      if (!std::isfinite(s)) return "non-finite state at vertex " + std::to_string(i);
    }
    return "non-finite state";
  }
  if (fastest > max_speed2) {
    for (std::size_t i = 0; i < n; ++i) {
      if (glm::dot(v[i], v[i]) > max_speed2) {
        return "vertex " + std::to_string(i) + " faster than " +
               std::to_string(options.max_speed_m_s) + " m/s";
      }
    }
  }
  if (!energy_check) return {};
  const double energy_after = kinetic + potential + elastic_after;
  if (!std::isfinite(energy_after)) return "non-finite energy";
  const double allowed = std::max(0.0, work) + options.energy_jump_J +
                         options.energy_jump_relative * std::abs(energy_before);
  if (energy_after - energy_before > allowed) {
    return "energy rose by " + std::to_string(energy_after - energy_before) + " J (allowed " +
           std::to_string(allowed) + " J)";
  }
  return {};
}

void ImplicitIntegrator::update_diagonal(System& st, const SoftBody& body, double h,
                                         const double (&w)[4]) {
  System::Diagonal& dg = st.diagonal;
  if (dg.system == st.id && dg.h == h && dg.members == members()) return;
  const std::size_t nf = st.vertex.size();
  const std::uint32_t* vertex = st.vertex.data();
  const std::uint32_t* free = st.free_count.data();
  const std::uint32_t* fixed = st.fixed_count.data();
  const auto& m = body.masses();
  const double drag = body.material().drag_per_s;
  dg.value.resize(nf);
  dg.self.resize(nf);
  dg.self_f.resize(nf);
  dg.inv.resize(4 * nf);
  dg.inv_f.resize(4 * nf);
  // The matrix: diagonal m (1 + h a) + sum of the spring weights, weights h^2 k + h c per class.
  // Per member the sum of the free vertices' squared masses, for the absolute tolerance.
  std::array<double, kMaxThreads> weight2_part{};
  run_parts(step_team_, nf, [&](std::size_t first, std::size_t last, unsigned t) {
    double weight2 = 0.0;
    for (std::size_t ci = first; ci < last; ++ci) {
      const std::uint32_t i = vertex[ci];
      double self = m[i] * (1.0 + h * drag), nbr = 0.0;
      for (std::size_t k = 0; k < 4; ++k) {
        self += double(fixed[4 * ci + k]) * w[k];
        nbr += double(free[4 * ci + k]) * w[k];
      }
      const double d = self + nbr;
      dg.value[ci] = d;
      dg.self[ci] = self;
      dg.self_f[ci] = static_cast<float>(self);
      const double inv = d > 0.0 ? 1.0 / d : 1.0;
      for (std::size_t l = 0; l < 4; ++l) {
        dg.inv[4 * ci + l] = l < 3 ? inv : 1.0;
        dg.inv_f[4 * ci + l] = static_cast<float>(dg.inv[4 * ci + l]);
      }
      weight2 += m[i] * m[i];
    }
    weight2_part[t] = weight2;
  });
  dg.weight2 = 0.0;
  for (const double w2 : weight2_part)
    dg.weight2 += w2;
  dg.system = st.id;
  dg.h = h;
  dg.members = members();
}

template <class T>
const T* ImplicitIntegrator::solve(System& st, const double (&w)[4],
                                   const std::vector<glm::dvec3>& warm, int max_iterations,
                                   double rel_tol2, double abs_tol2, StepStats& stats) {
  const std::size_t nf = st.vertex.size();
  const std::size_t n4 = 4 * nf;
  CgData<T> d;
  d.nf = nf;
  d.row = st.prow.data();
  d.col = st.pcol.data();
  for (int k = 0; k < 4; ++k)
    d.w[k] = static_cast<T>(w[k]);
  d.contact = contacts_.data();
  d.contacts = contacts_.size() / 5;
  if (step_team_ != nullptr) {
    // Rows split by their entries, so each member gathers about as much.
    const unsigned n = step_team_->size();
    row_parts_.resize(n + 1);
    const std::uint32_t entries = nf > 0 ? st.prow[nf] : 0;
    for (unsigned t = 0; t <= n; ++t) {
      const std::uint64_t goal = std::uint64_t{entries} * t / n;
      row_parts_[t] = static_cast<std::uint32_t>(
          std::lower_bound(st.prow.begin(), st.prow.begin() + static_cast<std::ptrdiff_t>(nf),
                           goal) -
          st.prow.begin());
    }
    row_parts_[n] = static_cast<std::uint32_t>(nf);
    d.team = step_team_;
    d.part = row_parts_.data();
  }
  double b2 = 0.0;
  {
    double b24[4] = {0.0, 0.0, 0.0, 0.0};
    for (std::size_t i = 0; i < n4; i += 4) {
      for (std::size_t l = 0; l < 4; ++l)
        b24[l] += rhs_[i + l] * rhs_[i + l];
    }
    b2 = (b24[0] + b24[1]) + (b24[2] + b24[3]);
  }
  // A solve starts when the residual is above either tolerance; once started, it goes on to a
  // tenth of the absolute one (or to the relative one): a body settling then leaves a residual
  // well under the threshold and its next steps cost no iteration, where stopping just under it
  // left every later step just above it (one or two iterations per step at rest).
  const double tol2 = std::max(rel_tol2 * b2, abs_tol2);
  d.stop2 = std::max(rel_tol2 * b2, 0.01 * abs_tol2);
  System::Diagonal& dg = st.diagonal;
  T* inv = nullptr;
  if constexpr (std::is_same_v<T, double>) {
    dbuf_.resize(3 * n4);
    dv_.resize(n4);
    inv = dg.inv.data();
    d.self = dg.self.data();
    d.b = rhs_.data();
    d.dv = dv_.data();
    d.r = dbuf_.data();
    d.p = d.r + n4;
    d.ap = d.p + n4;
  } else {
    // Layout: r, p, ap, dv, b (4 lanes each).
    fbuf_.resize(5 * n4);
    float* f = fbuf_.data();
    d.r = f;
    d.p = f + n4;
    d.ap = f + 2 * n4;
    d.dv = f + 3 * n4;
    float* b = f + 4 * n4;
    for (std::size_t e = 0; e < n4; ++e)
      b[e] = static_cast<float>(rhs_[e]);
    inv = dg.inv_f.data();
    d.self = dg.self_f.data();
    d.b = b;
  }
  // The start: the warm start, except when dv = 0 already meets the absolute tolerance: then it
  // is the answer (the warm start would meet it too, but applying it again step after step keeps
  // a resting body moving at the tolerance's level).
  {
    const std::uint32_t* vertex = st.vertex.data();
    const bool zero = b2 <= abs_tol2;
    for (std::size_t i = 0; i < nf; ++i) {
      const glm::dvec3 w0 = zero ? glm::dvec3(0.0) : warm[vertex[i]];
      d.dv[4 * i] = static_cast<T>(w0.x);
      d.dv[4 * i + 1] = static_cast<T>(w0.y);
      d.dv[4 * i + 2] = static_cast<T>(w0.z);
      d.dv[4 * i + 3] = T(0);
    }
  }
  // The contact rows' inverses, with their blocks, for this solve (restored below).
  for (const ContactRow& row : contact_rows_) {
    const bool ok = row.d[0] > 0.0 && row.d[1] > 0.0 && row.d[2] > 0.0;
    for (std::size_t l = 0; l < 3; ++l)
      inv[std::size_t{4} * row.row + l] = static_cast<T>(ok ? 1.0 / row.d[l] : 1.0);
  }
  d.inv = inv;
  if (!st.agg.empty() && st.coarse_h > 0.0) {
    d.nc = st.coarse_count;
    d.agg = st.agg.data();
    if constexpr (std::is_same_v<T, double>) {
      d.chol = st.coarse.data();
    } else {
      d.chol = st.coarse_f.data();
    }
    d.chol_first = st.coarse_first.data();
    d.chol_start = st.coarse_start.data();
    // rc, xc, and a coarse vector for each member after the first.
    const std::size_t members = step_team_ != nullptr ? step_team_->size() : 1;
    const std::size_t size = 4 * d.nc * (members + 1);
    T* cbuf = nullptr;
    if constexpr (std::is_same_v<T, double>) {
      cbuf_d_.assign(size, 0.0);
      cbuf = cbuf_d_.data();
    } else {
      cbuf_f_.assign(size, 0.0f);
      cbuf = cbuf_f_.data();
    }
    d.rc = cbuf;
    d.xc = d.rc + 4 * d.nc;
    d.rc_parts = d.xc + 4 * d.nc;
  }
  double r2 = 0.0;
  const int it = run_cg(d, max_iterations, tol2, r2);
  for (const ContactRow& row : contact_rows_) {
    for (std::size_t l = 0; l < 3; ++l)
      inv[std::size_t{4} * row.row + l] = static_cast<T>(dg.inv[std::size_t{4} * row.row + l]);
  }
  stats.cg_iterations += it;
  stats.relative_residual = std::sqrt(r2 / std::max(b2, 1e-300));
  return d.dv;
}

double ImplicitIntegrator::fixed_energy(System& sys, const SoftBody& body) {
  if (!sys.fixed_energy_valid) {
    const System::SpringSet& sx = sys.fixed;
    sys.fixed_energy = spring_energy(sx.a.data(), sx.b.data(), sx.rest.data(), sx.k.data(),
                                     sx.a.size(), body.positions().data());
    sys.fixed_energy_valid = true;
  }
  return sys.fixed_energy;
}

double ImplicitIntegrator::spring_pass(System& sys, const SoftBody& body, double h, bool energy) {
  const auto& x = body.positions();
  const auto& v = body.velocities();
  const double c = body.material().spring_damping_N_s_per_m;
  f_.assign(x.size(), glm::dvec3(0.0));
  // Member t takes a run of the springs into its own force array (member 0 into f_), then the
  // arrays are added in member order, each member a run of vertices.
  const System::SpringSet& sa = sys.active;
  f_parts_.resize(members() - 1);
  std::array<double, kMaxThreads> partial{};
  run_parts(
      step_team_, sa.a.size(),
      [&](std::size_t first, std::size_t last, unsigned t) {
        glm::dvec3* f = member_array(f_, f_parts_, t);
        const std::size_t real = sa.count > first ? std::min(sa.count, last) - first : 0;
        const std::size_t m = last - first;
        if (energy) {
          partial[t] =
              spring_forces_energy(sa.a.data() + first, sa.b.data() + first, sa.rest.data() + first,
                                   sa.k.data() + first, m, real, x.data(), v.data(), c, h, f);
        } else {
          spring_forces(sa.a.data() + first, sa.b.data() + first, sa.rest.data() + first,
                        sa.k.data() + first, m, real, x.data(), v.data(), c, h, f);
        }
      },
      kChunk);
  add_parts(f_, f_parts_);
  double elastic = 0.0;
  if (energy) {
    for (unsigned t = 0; t < members(); ++t)
      elastic += partial[t];
    elastic += fixed_energy(sys, body);
  }
  // The halo completes the spring forces on the border of the awake region (for waking).
  const System::SpringSet& sb = sys.halo;
  if (sb.count > 0) {
    spring_forces(sb.a.data(), sb.b.data(), sb.rest.data(), sb.k.data(), sb.a.size(), sb.count,
                  x.data(), v.data(), c, h, f_.data());
  }
  return elastic;
}

void ImplicitIntegrator::add_parts(std::vector<glm::dvec3>& into,
                                   const std::vector<std::vector<glm::dvec3>>& parts) {
  if (parts.empty()) return;  // one thread: `into` has everything
  // Each member a run of vertices; the arrays are added in member order.
  run_parts(step_team_, into.size(), [&](std::size_t first, std::size_t last, unsigned) {
    for (std::size_t i = first; i < last; ++i) {
      glm::dvec3 s = into[i];
      for (const auto& part : parts)
        s += part[i];
      into[i] = s;
    }
  });
}

double ImplicitIntegrator::volume_pass(const SoftBody& body) {
  const auto& x = body.positions();
  const std::uint32_t* idx = body.triangles().indices.data();
  const std::size_t nt = body.triangles().size();
  grad_.assign(x.size(), glm::dvec3(0.0));
  // Member t takes a run of the triangles into its own gradient array (member 0 into grad_).
  const unsigned n = members();
  grad_parts_.resize(n - 1);
  std::array<double, kMaxThreads> partial{};
  run_parts(step_team_, nt, [&](std::size_t first, std::size_t last, unsigned t) {
    partial[t] = volume_gradient(idx, first, last, x.data(), member_array(grad_, grad_parts_, t));
  });
  add_parts(grad_, grad_parts_);
  double six_v = 0.0;
  for (unsigned t = 0; t < n; ++t)
    six_v += partial[t];
  return six_v;
}

double ImplicitIntegrator::end_pass(Structure& st, System& sys, const SoftBody& body,
                                    const IntegratorOptions& options) {
  // The passes the next step starts with, at the state it will start from: the guard's spring
  // and volume energies come out of them, and the next step need not take them again.
  Structure::Ahead& ahead = st.ahead;
  ahead.h = options.dt_s;
  ahead.elastic = spring_pass(sys, body, ahead.h, true);
  ahead.six_v = 0.0;
  double elastic = ahead.elastic;
  if (body.closed() && body.rest_volume_m3() > 0.0) {
    ahead.six_v = volume_pass(body);
    const double v0 = body.rest_volume_m3();
    const double dv = body.orientation() * (ahead.six_v / 6.0) - v0;
    elastic += 0.5 * body.material().bulk_modulus_Pa * dv * dv / v0;
  }
  ahead.system = sys.id;
  ahead.members = members();
  f_.swap(ahead.f);
  grad_.swap(ahead.grad);
  return elastic;
}

unsigned ImplicitIntegrator::members() const {
  return step_team_ != nullptr ? step_team_->size() : 1;
}

StepThreads* ImplicitIntegrator::team(const IntegratorOptions& options) {
  const unsigned want = std::min(options.threads, kMaxThreads);
  if (want <= 1) return nullptr;
  if (!team_ || team_->size() != want) team_ = std::make_shared<StepThreads>(want);
  return team_.get();
}

ImplicitIntegrator::System& ImplicitIntegrator::substep(SoftBody& body, Structure& st,
                                                        const IntegratorOptions& options, double h,
                                                        double fraction, StepStats& stats,
                                                        double* energy_out, bool reuse_ahead) {
  auto& x = body.positions();
  auto& v = body.velocities();
  const auto& m = body.masses();
  const auto& fext = body.external_forces();
  const Material& mat = body.material();
  const std::size_t n = x.size();
  const double drag = mat.drag_per_s;
  const double c = mat.spring_damping_N_s_per_m;
  const glm::dvec3 g = options.gravity_m_s2;
  const double h2 = h * h;

  // Constraints: anchored and massless vertices stand still, kinematic ones follow their target.
  // Vertices with an external load are noted: they may not sleep.
  free_.resize(n);
  loaded_.clear();
  double kinetic = 0.0, potential = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const VertexId vi(static_cast<std::uint32_t>(i));
    std::uint8_t is_free = 1;
    if (m[i] <= 0.0 || body.anchored(vi)) {
      is_free = 0;
      v[i] = glm::dvec3(0.0);
    } else if (body.kinematic(vi)) {
      is_free = 0;
      // The target is reached at the end of the step; substeps follow the straight line.
      const glm::dvec3 goal = saved_x_[i] + (body.kinematic_target(vi) - saved_x_[i]) * fraction;
      v[i] = (goal - x[i]) / h;
    }
    free_[i] = is_free;
    if (fext[i] != glm::dvec3(0.0)) loaded_.push_back(static_cast<std::uint32_t>(i));
    if (energy_out) {
      kinetic += 0.5 * m[i] * glm::dot(v[i], v[i]);
      potential -= m[i] * glm::dot(g, x[i]);
    }
  }
  update_free_rows(st, free_, m);
  if (st.asleep > 0) wake_loaded(st, body);
  System* sys = &system(st, body);

  // Springs with a solved end: forces and the h^2 H v term of the right-hand side (H = k I per
  // spring). The others only add their (constant) energy to the start state's. The last step's
  // end_pass took them (and the volume pass) at this state already, if nothing changed since.
  Structure::Ahead& ahead = st.ahead;
  const bool reuse = reuse_ahead && ahead.system == sys->id && ahead.h == h;
  double spring_energy = 0.0;
  if (reuse) {
    f_.swap(ahead.f);
    spring_energy = ahead.elastic;
    stats.reused_end_pass = true;
  } else {
    spring_energy = spring_pass(*sys, body, h, energy_out != nullptr);
  }

  // Volume term (explicit): p dV/dx_i, p = K (V0 - V) / V0. 6 dV/dx_i is the sum over the
  // triangles around i of x_j x x_k; around a closed fan that equals the sum of the triangles'
  // area vectors (x_j - x_i) x (x_k - x_i) (the x_i x (x_k - x_j) terms telescope to zero), the
  // same vector for all three corners: one cross product per triangle instead of three. The
  // volume comes out of the same pass (x_0 . N = x_0 . (x_1 x x_2)). The term applies to closed
  // bodies only, whose fans are closed.
  double p6 = 0.0, volume_energy = 0.0;
  const bool volume_term = body.closed() && body.rest_volume_m3() > 0.0;
  if (volume_term) {
    double six_v = ahead.six_v;
    if (reuse) {
      grad_.swap(ahead.grad);
    } else {
      six_v = volume_pass(body);
    }
    const double volume = body.orientation() * (six_v / 6.0);  // as SoftBody::volume_m3()
    const double v0 = body.rest_volume_m3();
    // volume_m3() is measured outward whatever the faces' winding; the gradient follows it.
    p6 = body.orientation() * mat.bulk_modulus_Pa * (v0 - volume) / v0 / 6.0;
    volume_energy = 0.5 * mat.bulk_modulus_Pa * (volume - v0) * (volume - v0) / v0;
  }
  p6_ = p6;
  // Sleeping aggregates whose residual can now exceed the tolerance wake; the forces are taken
  // again over the larger awake region.
  if (st.asleep > 0 && wake_by_forces(st, *sys, body, options, p6)) {
    sys = &system(st, body);
    spring_energy = spring_pass(*sys, body, h, energy_out != nullptr);
  }
  if (energy_out) *energy_out = kinetic + potential + spring_energy + volume_energy;
  const std::size_t nf = sys->vertex.size();
  const std::uint32_t* vertex = sys->vertex.data();
  const std::uint32_t* full_compact = st.full.compact.data();
  const std::uint32_t* full_agg = st.full.agg.data();

  // The right-hand side and the diagonal over the free vertices, four lanes per vertex
  // (x, y, z and a zero pad: the loops below run on whole vectors the compiler vectorises).
  // The matrix: diagonal m (1 + h a) + sum of the spring weights, weights h^2 k + h c per class.
  double w[4];
  for (int k = 0; k < 4; ++k)
    w[k] = h2 * st.k_class[k] + h * c;
  const std::size_t n4 = 4 * nf;
  update_diagonal(*sys, body, h, w);
  const System::Diagonal& dg = sys->diagonal;
  rhs_.resize(n4);
  row_residual_.resize(nf);
  row_gradient_.resize(nf);
  // The rows split over the team: per row its residual force and pressure gradient (squared),
  // summed per aggregate below in row order.
  run_parts(step_team_, nf, [&](std::size_t first, std::size_t last, unsigned) {
    for (std::size_t ci = first; ci < last; ++ci) {
      const std::uint32_t i = vertex[ci];
      glm::dvec3 f = m[i] * g + fext[i] - drag * m[i] * v[i] + f_[i];
      if (volume_term) f += p6 * grad_[i];
      // A loaded vertex does not sleep (the load is applied again step after step).
      row_residual_[ci] = fext[i] != glm::dvec3(0.0) ? kNeverQuiet : glm::dot(f, f);
      row_gradient_[ci] = volume_term ? glm::dot(grad_[i], grad_[i]) : 0.0;
      rhs_[4 * ci] = h * f.x;
      rhs_[4 * ci + 1] = h * f.y;
      rhs_[4 * ci + 2] = h * f.z;
      rhs_[4 * ci + 3] = 0.0;
    }
  });
  const double weight2 = dg.weight2;
  // Per aggregate, for sleeping: the sums over its vertices of the squared residual force and
  // pressure gradient.
  std::fill(st.step_residual.begin(), st.step_residual.end(), 0.0);
  std::fill(st.step_gradient.begin(), st.step_gradient.end(), 0.0);
  for (std::size_t ci = 0; ci < nf; ++ci) {
    const std::uint32_t A = full_agg[full_compact[vertex[ci]]];
    st.step_residual[A] += row_residual_[ci];
    if (volume_term) st.step_gradient[A] += row_gradient_[ci];
  }
  // Contacts: k n n^T blocks on the diagonal, their h^2 H v term on the right-hand side.
  contacts_.clear();
  contact_rows_.clear();
  if (contact_slot_.size() < nf) contact_slot_.resize(nf, kNotFree);
  for (const SoftBody::ContactTerm& ct : body.contacts()) {
    const std::uint32_t i = ct.vertex;
    if (i >= n || !free_[i]) continue;
    const std::size_t ci = sys->compact[i];
    st.step_residual[full_agg[full_compact[i]]] = kNeverQuiet;
    const double kc = h2 * ct.stiffness_N_per_m;
    const glm::dvec3 nn = ct.normal;
    contacts_.insert(contacts_.end(), {double(ci), nn.x, nn.y, nn.z, kc});
    const double nv = kc * glm::dot(nn, v[i]);
    rhs_[4 * ci] -= nv * nn.x;
    rhs_[4 * ci + 1] -= nv * nn.y;
    rhs_[4 * ci + 2] -= nv * nn.z;
    std::uint32_t& slot = contact_slot_[ci];
    if (slot == kNotFree) {
      slot = static_cast<std::uint32_t>(contact_rows_.size());
      const double d = dg.value[ci];
      contact_rows_.push_back({static_cast<std::uint32_t>(ci), {d, d, d}});
    }
    double* d = contact_rows_[slot].d;
    d[0] += kc * nn.x * nn.x;
    d[1] += kc * nn.y * nn.y;
    d[2] += kc * nn.z * nn.z;
  }
  for (const ContactRow& row : contact_rows_)
    contact_slot_[row.row] = kNotFree;
  // The solve starts from the warm start, the last step's dv. It stops at the relative tolerance
  // or when the residual force is below the absolute one (see IntegratorOptions).
  auto& warm = body.warm_start();
  const double g2 = glm::dot(g, g);
  const double frac2 = options.cg_weight_fraction * options.cg_weight_fraction;
  const double floor2 = options.cg_force_floor_N * options.cg_force_floor_N;
  const double abs_tol2 = h2 * (frac2 * g2 * weight2 + floor2 * double(nf));
  const double rel_tol2 = options.cg_relative_tolerance * options.cg_relative_tolerance;
  // float reaches a relative residual of about 1e-6 (its rounding of b and A p): below 1e-5
  // the solve runs in double.
  if (options.cg_coarse_level) {
    update_coarse(*sys, st, body, h);
  } else {
    sys->coarse_h = -1.0;  // keeps solve() on Jacobi alone
  }
  // v += dv (solved vertices only), x += h v (every vertex with mass); the warm start keeps dv.
  // Per aggregate, for sleeping: the sum over its vertices of the squared force that one more
  // step at their speed would add to their residual (the diagonal, inertia and springs, times
  // the speed over h): a vertex stopped while it moves that much was not at rest.
  row_speed_.resize(nf);
  const auto apply = [&](const auto* dvs) {
    run_parts(step_team_, nf, [&](std::size_t first, std::size_t last, unsigned) {
      for (std::size_t ci = first; ci < last; ++ci) {
        const std::uint32_t i = vertex[ci];
        const glm::dvec3 d{double(dvs[4 * ci]), double(dvs[4 * ci + 1]), double(dvs[4 * ci + 2])};
        warm[i] = d;
        v[i] += d;
        const double stop = dg.value[ci] / h;
        row_speed_[ci] = stop * stop * glm::dot(v[i], v[i]);
      }
    });
  };
  if (options.cg_relative_tolerance >= 1e-5) {
    apply(solve<float>(*sys, w, warm, options.max_cg_iterations, rel_tol2, abs_tol2, stats));
  } else {
    apply(solve<double>(*sys, w, warm, options.max_cg_iterations, rel_tol2, abs_tol2, stats));
  }
  // Vertices outside the solve keep no warm start.
  const std::uint32_t* compact = sys->compact.data();
  run_parts(step_team_, n, [&](std::size_t first, std::size_t last, unsigned) {
    for (std::size_t i = first; i < last; ++i) {
      if (compact[i] == kNotFree) warm[i] = glm::dvec3(0.0);
      if (m[i] > 0.0) x[i] += h * v[i];
    }
  });
  std::fill(st.step_speed.begin(), st.step_speed.end(), 0.0);
  for (std::size_t ci = 0; ci < nf; ++ci)
    st.step_speed[full_agg[full_compact[vertex[ci]]]] += row_speed_[ci];
  return *sys;
}

}  // namespace bisturi::sim
