#include "weld.h"

#include <array>
#include <bit>
#include <cmath>
#include <string>
#include <vector>

#include "bisturi/scene/errors.h"
#include "prefault.h"

namespace bisturi::construction {

namespace {

constexpr std::uint32_t kEmpty = 0xffffffffu;

std::uint64_t mix(std::uint64_t h) {
  // splitmix64 finaliser: spreads nearby coordinates over the table.
  h ^= h >> 30;
  h *= 0xbf58476d1ce4e5b9ull;
  h ^= h >> 27;
  h *= 0x94d049bb133111ebull;
  h ^= h >> 31;
  return h;
}

std::uint64_t hash_bits(double x, double y, double z) {
  // Adding 0.0 turns -0.0 into +0.0 so both hash (and compare) alike.
  const std::uint64_t a = std::bit_cast<std::uint64_t>(x + 0.0);
  const std::uint64_t b = std::bit_cast<std::uint64_t>(y + 0.0);
  const std::uint64_t c = std::bit_cast<std::uint64_t>(z + 0.0);
  return mix(a ^ mix(b ^ mix(c)));
}

std::size_t table_size_for(std::size_t n) {
  std::size_t size = 16;
  while (size < 2 * n)
    size *= 2;
  return size;
}

}  // namespace

WeldResult weld_exact(std::span<const Dlfl::Vec3> positions) {
  WeldResult out;
  const std::size_t n = positions.size();
  reserve_mapped(out.welded_index, n);
  out.welded_index.resize(n);
  // Open addressing, linear probing, at most 3/4 full. Fresh memory is slow here and a soup
  // keeps about one vertex in six, so the table starts small and doubles when it fills.
  std::size_t size = 16;
  while (3 * size < n)
    size *= 2;
  std::size_t mask = size - 1;
  auto slot_of = [](const Dlfl::Vec3& p) { return hash_bits(p.x, p.y, p.z); };
  // Pass 1: the table holds the first input vertex of every place; each vertex notes its first.
  ScratchVector<std::uint32_t> table;
  reserve_mapped(table, size);
  table.assign(size, kEmpty);
  std::size_t kept = 0;
  // Places recur close together in a soup (the faces around a vertex are near in the file): a
  // small cache of recent places, holding their coordinates, answers most repeats from L2
  // instead of a table probe plus a random read of the first vertex's coordinates.
  struct Recent {
    Dlfl::Vec3 p;
    std::uint32_t first = kEmpty;
  };
  constexpr std::size_t kRecent = std::size_t{1} << 14;
  const std::size_t recent_size = n >= 4 * kRecent ? kRecent : 0;
  std::vector<Recent> recent;
  reserve_mapped(recent, recent_size);
  recent.resize(recent_size);
  for (std::size_t i = 0; i < n; ++i) {
    const Dlfl::Vec3& p = positions[i];
    const std::uint64_t hash = slot_of(p);
    Recent* cached = nullptr;
    if (!recent.empty()) {
      cached = &recent[(hash >> 40) & (kRecent - 1)];
      if (cached->first != kEmpty && cached->p.x == p.x && cached->p.y == p.y &&
          cached->p.z == p.z) {
        out.welded_index[i] = cached->first;
        continue;
      }
    }
    std::size_t slot = hash & mask;
    while (true) {
      const std::uint32_t first = table[slot];
      if (first == kEmpty) {
        table[slot] = static_cast<std::uint32_t>(i);
        out.welded_index[i] = static_cast<std::uint32_t>(i);
        ++kept;
        break;
      }
      const Dlfl::Vec3& q = positions[first];
      if (p.x == q.x && p.y == q.y && p.z == q.z) {
        out.welded_index[i] = first;
        break;
      }
      slot = (slot + 1) & mask;
    }
    if (cached != nullptr) *cached = {p, out.welded_index[i]};
    if (4 * kept > 3 * size) {
      ScratchVector<std::uint32_t> bigger;
      reserve_mapped(bigger, 2 * size);
      bigger.assign(2 * size, kEmpty);
      const std::size_t bigger_mask = 2 * size - 1;
      for (const std::uint32_t first : table) {
        if (first == kEmpty) continue;
        std::size_t s = slot_of(positions[first]) & bigger_mask;
        while (bigger[s] != kEmpty)
          s = (s + 1) & bigger_mask;
        bigger[s] = first;
      }
      table = std::move(bigger);
      size *= 2;
      mask = bigger_mask;
    }
  }
  // Pass 2: kept vertices numbered in order of first appearance, into an exactly sized array.
  // A repeat's first vertex comes earlier, so it is already renumbered.
  reserve_mapped(out.positions, kept);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t first = out.welded_index[i];
    if (first == i) {
      out.welded_index[i] = static_cast<std::uint32_t>(out.positions.size());
      out.positions.push_back(positions[i]);
    } else {
      out.welded_index[i] = out.welded_index[first];
    }
  }
  return out;
}

WeldResult weld_within(std::span<const Dlfl::Vec3> positions, double tolerance) {
  WeldResult out;
  out.welded_index.resize(positions.size());
  const double limit = 9.0e15;  // cell indices stay exact in double and fit in int64
  auto cell_of = [&](const Dlfl::Vec3& p, std::size_t i) {
    const double cx = std::floor(p.x / tolerance);
    const double cy = std::floor(p.y / tolerance);
    const double cz = std::floor(p.z / tolerance);
    if (!(std::fabs(cx) < limit && std::fabs(cy) < limit && std::fabs(cz) < limit)) {
      throw InputError("vertex " + std::to_string(i) +
                       ": coordinates too large for a weld tolerance of " +
                       std::to_string(tolerance));
    }
    return std::array<std::int64_t, 3>{static_cast<std::int64_t>(cx), static_cast<std::int64_t>(cy),
                                       static_cast<std::int64_t>(cz)};
  };
  auto cell_hash = [](std::int64_t x, std::int64_t y, std::int64_t z) {
    return mix(static_cast<std::uint64_t>(x) ^
               mix(static_cast<std::uint64_t>(y) ^ mix(static_cast<std::uint64_t>(z))));
  };
  // Cells hold chains of kept vertices: table slot -> first kept vertex, next_in_cell links.
  const std::size_t size = table_size_for(positions.size());
  const std::size_t mask = size - 1;
  ScratchVector<std::uint32_t> table(size, kEmpty);
  ScratchVector<std::array<std::int64_t, 3>> cell_of_slot(size);
  ScratchVector<std::uint32_t> next_in_cell;
  const double tol2 = tolerance * tolerance;
  auto find_slot = [&](const std::array<std::int64_t, 3>& c) {
    std::size_t slot = cell_hash(c[0], c[1], c[2]) & mask;
    while (table[slot] != kEmpty && cell_of_slot[slot] != c)
      slot = (slot + 1) & mask;
    return slot;
  };
  for (std::size_t i = 0; i < positions.size(); ++i) {
    const Dlfl::Vec3& p = positions[i];
    const auto c = cell_of(p, i);
    std::uint32_t found = kEmpty;
    for (int dz = -1; dz <= 1 && found == kEmpty; ++dz) {
      for (int dy = -1; dy <= 1 && found == kEmpty; ++dy) {
        for (int dx = -1; dx <= 1 && found == kEmpty; ++dx) {
          const std::size_t slot = find_slot({c[0] + dx, c[1] + dy, c[2] + dz});
          for (std::uint32_t k = table[slot]; k != kEmpty; k = next_in_cell[k]) {
            const Dlfl::Vec3 d = out.positions[k] - p;
            if (d.x * d.x + d.y * d.y + d.z * d.z <= tol2) {
              found = k;
              break;
            }
          }
        }
      }
    }
    if (found == kEmpty) {
      found = static_cast<std::uint32_t>(out.positions.size());
      out.positions.push_back(p);
      const std::size_t slot = find_slot(c);
      cell_of_slot[slot] = c;
      next_in_cell.push_back(table[slot]);
      table[slot] = found;
    }
    out.welded_index[i] = found;
  }
  return out;
}

}  // namespace bisturi::construction
