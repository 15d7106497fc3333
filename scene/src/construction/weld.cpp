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
  // Kept places, numbered as they first appear. The table compares against this compact array
  // (recent places are near each other in it), not against the whole input. Reserved for every
  // vertex but not mapped: only what is written costs memory.
  ScratchVector<Dlfl::Vec3> kept;
  kept.reserve(n);
  // Open addressing, linear probing, at most 3/4 full. Fresh memory is slow here and a soup
  // keeps about one vertex in six, so the table starts small and doubles when it fills. A slot
  // holds the hash's high half beside the kept number: a probe past another place mostly
  // rejects it without reading that place's coordinates (a cache miss).
  constexpr std::uint64_t kEmptySlot = ~std::uint64_t{0};
  constexpr std::uint64_t kTagBits = 0xffffffff00000000ull;
  std::size_t size = 16;
  while (3 * size < n)
    size *= 2;
  std::size_t mask = size - 1;
  ScratchVector<std::uint64_t> table;
  reserve_mapped(table, size);
  table.assign(size, kEmptySlot);
  auto hash_of = [](const Dlfl::Vec3& p) { return hash_bits(p.x, p.y, p.z); };
  // The time goes in cache misses on the table: each vertex's slot is prefetched kAhead
  // vertices early (its hash kept until then), so the misses of several vertices overlap.
  constexpr std::size_t kAhead = 16;
  std::array<std::uint64_t, kAhead> ahead{};
  for (std::size_t i = 0; i < kAhead && i < n; ++i) {
    ahead[i] = hash_of(positions[i]);
    __builtin_prefetch(&table[ahead[i] & mask]);
  }
  for (std::size_t i = 0; i < n; ++i) {
    const Dlfl::Vec3& p = positions[i];
    const std::uint64_t hash = ahead[i % kAhead];
    if (i + kAhead < n) {
      const std::uint64_t later = hash_of(positions[i + kAhead]);
      ahead[i % kAhead] = later;
      __builtin_prefetch(&table[later & mask]);
    }
    for (std::size_t slot = hash & mask;; slot = (slot + 1) & mask) {
      const std::uint64_t entry = table[slot];
      if (entry == kEmptySlot) {
        const auto k = static_cast<std::uint32_t>(kept.size());
        table[slot] = (hash & kTagBits) | k;
        kept.push_back(p);
        out.welded_index[i] = k;
        break;
      }
      const auto k = static_cast<std::uint32_t>(entry);
      if ((entry & kTagBits) != (hash & kTagBits)) continue;
      const Dlfl::Vec3& q = kept[k];
      if (p.x == q.x && p.y == q.y && p.z == q.z) {
        out.welded_index[i] = k;
        break;
      }
    }
    if (4 * kept.size() > 3 * size) {
      size *= 2;
      mask = size - 1;
      ScratchVector<std::uint64_t> bigger;
      reserve_mapped(bigger, size);
      bigger.assign(size, kEmptySlot);
      for (std::uint32_t k = 0; k < kept.size(); ++k) {
        const std::uint64_t h = hash_of(kept[k]);
        std::size_t s = h & mask;
        while (bigger[s] != kEmptySlot)
          s = (s + 1) & mask;
        bigger[s] = (h & kTagBits) | k;
      }
      table = std::move(bigger);
    }
  }
  // Sized exactly, so the DLFL can take them as they are.
  reserve_mapped(out.positions, kept.size());
  out.positions.assign(kept.begin(), kept.end());
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
