// detail::HashIdTable (buildCflModel's list deduplication) against std::unordered_map on random items:
// every lookup must find exactly the item the map finds, whatever the hashes' collisions.

#include "../src/detail/hash_id_table.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <unordered_map>
#include <vector>

namespace cfl {
namespace {

// Deduplicates `items` through the table with `hash_of` as their hash; returns each item's id (the index of
// its first occurrence among the distinct items).
template <typename HashOf>
std::vector<std::uint32_t> dedupWithTable(const std::vector<std::uint64_t>& items, const HashOf& hash_of,
                                          std::vector<std::uint64_t>* distinct) {
  detail::HashIdTable table = detail::makeHashIdTable(items.size());
  std::vector<std::uint32_t> ids;
  for (std::uint64_t item : items) {
    const std::uint64_t hash = hash_of(item);
    const detail::HashIdProbe probe =
        detail::findHashId(table, hash, [&](std::uint32_t id) { return (*distinct)[id] == item; });
    std::uint32_t id = probe.id;
    if (id == detail::kNoHashId) {
      id = static_cast<std::uint32_t>(distinct->size());
      distinct->push_back(item);
      detail::insertHashId(table, probe.slot, hash, id);
    }
    ids.push_back(id);
  }
  return ids;
}

// The reference: the map the builder used before, item by value.
std::vector<std::uint32_t> dedupWithMap(const std::vector<std::uint64_t>& items) {
  std::unordered_map<std::uint64_t, std::uint32_t> map;
  std::vector<std::uint32_t> ids;
  for (std::uint64_t item : items) {
    const auto inserted = map.emplace(item, static_cast<std::uint32_t>(map.size()));
    ids.push_back(inserted.first->second);
  }
  return ids;
}

// Items drawn from a pool of `pool` values, so that many repeat.
std::vector<std::uint64_t> randomItems(std::size_t count, std::size_t pool, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<std::uint64_t> values(pool);
  for (auto& v : values) v = rng();
  std::vector<std::uint64_t> items(count);
  std::uniform_int_distribution<std::size_t> pick(0, pool - 1);
  for (auto& item : items) item = values[pick(rng)];
  return items;
}

TEST(HashIdTable, MatchesUnorderedMapOnRandomKeys) {
  for (std::uint64_t seed : {1, 2, 3}) {
    for (std::size_t pool : {1, 7, 1000, 200000}) {
      const std::vector<std::uint64_t> items = randomItems(100000, pool, seed);
      std::vector<std::uint64_t> distinct;
      const auto ids = dedupWithTable(items, [](std::uint64_t x) { return x * 0xff51afd7ed558ccdull; }, &distinct);
      EXPECT_EQ(ids, dedupWithMap(items)) << "seed " << seed << " pool " << pool;
    }
  }
}

// Hashes that collide: all the same, in a few values, equal in their high half only, or in their low half
// only (the table keeps the high half as a tag and picks the home slot from the whole hash). Distinct
// items with one hash must still be told apart by the comparison, and equal ones found.
TEST(HashIdTable, MatchesUnorderedMapWhenHashesCollide) {
  const std::vector<std::uint64_t> items = randomItems(20000, 3000, 9);
  const auto reference = dedupWithMap(items);
  using Hash = std::uint64_t (*)(std::uint64_t);
  const std::vector<std::pair<const char*, Hash>> hashes = {
      {"constant", +[](std::uint64_t) { return std::uint64_t(42); }},
      {"four values", +[](std::uint64_t x) { return std::uint64_t(x % 4) << 40; }},
      {"high half only", +[](std::uint64_t x) { return std::uint64_t(x % 97) << 32; }},
      {"low half only", +[](std::uint64_t x) { return std::uint64_t(x & 0xffffffffull); }},
      {"zero", +[](std::uint64_t) { return std::uint64_t(0); }},
  };
  for (const auto& [name, hash] : hashes) {
    std::vector<std::uint64_t> distinct;
    EXPECT_EQ(dedupWithTable(items, hash, &distinct), reference) << name;
    EXPECT_EQ(distinct.size(), std::size_t(*std::max_element(reference.begin(), reference.end()) + 1)) << name;
  }
}

TEST(HashIdTable, IsAtMostHalfFullAtCapacity) {
  for (std::size_t capacity : {0, 1, 2, 3, 1000, 1024, 1025}) {
    const detail::HashIdTable table = detail::makeHashIdTable(capacity);
    EXPECT_GE(table.slots.size(), 2 * capacity);
    EXPECT_EQ(table.slots.size() & (table.slots.size() - 1), 0u);
    EXPECT_EQ(std::uint64_t(1) << (64 - table.shift), table.slots.size());
  }
}

}  // namespace
}  // namespace cfl
