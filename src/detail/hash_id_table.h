#pragma once
/// @file
/// Internal: a flat open-addressing table from 64-bit hashes to 32-bit ids, several ids per hash allowed,
/// for deduplicating items stored elsewhere (buildCflModel's identical lists). It replaces a node-based
/// std::unordered_map of vectors, one allocation per distinct item; here there is one array, sized once.

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace cfl::detail {

/// Each slot holds (the hash's high 32 bits << 32) | (id + 1); 0 marks an empty slot. Linear probing from
/// the slot the hash picks; a slot's neighbours are never removed, so a probe ends at the first empty slot.
struct HashIdTable {
  std::vector<std::uint64_t> slots;  ///< A power of two of them, at least twice the capacity asked.
  int shift = 64;                    ///< 64 - log2(slots.size()): a hash's home slot is (hash * kMix) >> shift.
};

/// The result of findHashId: the id found, or kNoHashId and the empty slot where the item goes.
struct HashIdProbe {
  std::uint32_t id;
  std::size_t slot;
};

constexpr std::uint32_t kNoHashId = std::numeric_limits<std::uint32_t>::max();

/// An empty table for up to `capacity` ids (ids below 2^32 - 1), at most half full.
inline HashIdTable makeHashIdTable(std::size_t capacity) {
  HashIdTable table;
  std::size_t size = 2;
  int bits = 1;
  while (size < 2 * capacity) size *= 2, ++bits;
  table.slots.assign(size, 0);
  table.shift = 64 - bits;
  return table;
}

/// The first id stored with `hash` for which same(id) holds, or kNoHashId and the slot insertHashId takes.
/// The ids are tested in the order they were inserted with that hash (and only where the hash's high 32
/// bits match), so same() may be expensive.
template <typename Same>
HashIdProbe findHashId(const HashIdTable& table, std::uint64_t hash, const Same& same) {
  // Fibonacci hashing: the product's high bits depend on every bit of the hash, whose own low bits may not.
  constexpr std::uint64_t kMix = 0x9e3779b97f4a7c15ull;
  const std::size_t mask = table.slots.size() - 1;
  const std::uint64_t tag = hash & 0xffffffff00000000ull;
  for (std::size_t slot = std::size_t((hash * kMix) >> table.shift);; slot = (slot + 1) & mask) {
    const std::uint64_t value = table.slots[slot];
    if (value == 0) return {kNoHashId, slot};
    if ((value & 0xffffffff00000000ull) == tag) {
      const std::uint32_t id = std::uint32_t(value) - 1;
      if (same(id)) return {id, slot};
    }
  }
}

/// Stores `id` with `hash` in `slot`, the empty slot findHashId just returned for that hash (no insertion
/// in between). At most the capacity the table was made for.
inline void insertHashId(HashIdTable& table, std::size_t slot, std::uint64_t hash, std::uint32_t id) {
  table.slots[slot] = (hash & 0xffffffff00000000ull) | (std::uint64_t(id) + 1);
}

}  // namespace cfl::detail
