#include "cfl/cfl_file.h"

#include "cfl/error.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <ostream>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <type_traits>

#include <zlib.h>

#if defined(__unix__) || defined(__APPLE__)
#include <unistd.h>
#endif

namespace cfl {
namespace {

static_assert(std::numeric_limits<double>::is_iec559 && sizeof(double) == 8,
              "the file stores doubles as IEEE-754 binary64 bit patterns");

// On a little-endian host the file's arrays have the memory layout of the vectors, so they are copied in
// bulk; elsewhere, or when built with -DCFL_FILE_BULK_COPY=0 (as the sanitizer CI build is, so that both
// paths are tested), every value goes through the byte-by-byte conversions.
#ifndef CFL_FILE_BULK_COPY
#if defined(__BYTE_ORDER__) && defined(__ORDER_LITTLE_ENDIAN__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__ && \
    (!defined(__FLOAT_WORD_ORDER__) || __FLOAT_WORD_ORDER__ == __ORDER_LITTLE_ENDIAN__)
#define CFL_FILE_BULK_COPY 1
#else
#define CFL_FILE_BULK_COPY 0
#endif
#endif
constexpr bool kBulkCopy = CFL_FILE_BULK_COPY != 0;

constexpr std::array<unsigned char, 8> kMagic = {0x89, 'C', 'F', 'L', '\r', '\n', 0x1A, '\n'};
constexpr std::uint32_t kEndianMarker = 0x01020304u;
constexpr std::size_t kHeaderSize = 32;
constexpr std::size_t kSectionHeaderSize = 16;

// Section tags are four ASCII bytes, read as a little-endian u32 so they compare as integers.
constexpr std::uint32_t makeTag(const char (&name)[5]) {
  return std::uint32_t(std::uint8_t(name[0])) | std::uint32_t(std::uint8_t(name[1])) << 8 |
         std::uint32_t(std::uint8_t(name[2])) << 16 | std::uint32_t(std::uint8_t(name[3])) << 24;
}
constexpr std::uint32_t kTagMesh = makeTag("MESH");
constexpr std::uint32_t kTagTree = makeTag("TREE");
constexpr std::uint32_t kTagNodes = makeTag("NODE");
constexpr std::uint32_t kTagLeaves = makeTag("LEAF");
constexpr std::uint32_t kTagList = makeTag("LIST");
constexpr std::uint32_t kTagEntryBounds = makeTag("LBND");
constexpr std::uint32_t kTagStatistics = makeTag("STAT");

// origin, root_size, root_dims, max_depth, padding, flags, corner_distance_unit.
constexpr std::size_t kTreeSectionSize = 3 * 8 + 8 + 3 * 4 + 4 + 8 + 4 + 8;
// Per leaf in LEAF: its list (u32), lower bound (f32) and eight corner distances (u16).
constexpr std::size_t kLeafRecordSize = 4 + 4 + 8 * 2;
// Eight 8-byte figures, the flags and the size of leaves_per_depth; its entries follow.
constexpr std::size_t kStatisticsFixedSize = 8 * 8 + 4 + 8;
// RegionTree::forEachLeafInBox keeps its pending cells in a fixed stack sized for this depth.
constexpr int kMaxTreeDepth = RegionTree::kMaxDepth;

using CornerDistances = std::array<std::uint16_t, 8>;
static_assert(sizeof(float) == 4 && std::numeric_limits<float>::is_iec559,
              "the file stores floats as IEEE-754 binary32 bit patterns");
static_assert(std::is_same_v<decltype(RegionTree::leaf_corner_distance)::value_type, CornerDistances> &&
                  sizeof(CornerDistances) == 8 * sizeof(std::uint16_t),
              "corner distances are copied in bulk as eight 16-bit integers");

std::uint32_t loadU32(const unsigned char* p) {
  return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 | std::uint32_t(p[3]) << 24;
}
std::uint64_t loadU64(const unsigned char* p) {
  return std::uint64_t(loadU32(p)) | std::uint64_t(loadU32(p + 4)) << 32;
}
void storeU32(unsigned char* p, std::uint32_t value) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<unsigned char>(value >> (8 * i));
}
void storeU64(unsigned char* p, std::uint64_t value) {
  for (int i = 0; i < 8; ++i) p[i] = static_cast<unsigned char>(value >> (8 * i));
}

std::string hexU32(std::uint32_t value) {
  char text[16];
  std::snprintf(text, sizeof(text), "0x%08x", value);
  return text;
}

std::string hexBytes(const unsigned char* data, std::size_t count) {
  std::string text;
  char byte[4];
  for (std::size_t i = 0; i < count; ++i) {
    std::snprintf(byte, sizeof(byte), i ? " %02x" : "%02x", data[i]);
    text += byte;
  }
  return text;
}

std::string tagName(std::uint32_t tag) {
  std::string name;
  for (int i = 0; i < 4; ++i) {
    const unsigned char c = static_cast<unsigned char>(tag >> (8 * i));
    name += (c >= 0x20 && c < 0x7F) ? static_cast<char>(c) : '?';
  }
  return name;
}

// Extends `crc`, the CRC-32 of some bytes (0 for none), to that of those bytes followed by `data`.
std::uint32_t crc32Update(std::uint32_t crc, const unsigned char* data, std::size_t size) {
  // zlib takes lengths as uInt (32 bits), so a larger buffer goes in slices.
  uLong value = crc;
  constexpr std::size_t kSlice = std::size_t(1) << 30;
  while (size > 0) {
    const std::size_t slice = std::min(size, kSlice);
    value = ::crc32(value, data, static_cast<uInt>(slice));
    data += slice;
    size -= slice;
  }
  return static_cast<std::uint32_t>(value);
}

// Streams little-endian values to `sink`, a callable taking (const unsigned char*, std::size_t), through a
// small buffer, so that no copy of the whole file is ever made: the sink sees the file as a few large
// pieces (on a little-endian host, arrays go to it straight from the model's memory) and buffer-sized
// chunks of converted values. Call finish() to pass on what is buffered.
template <typename Sink>
class Writer {
 public:
  explicit Writer(Sink& sink) : sink_(sink), buffer_(kBufferSize) {}
  void u32(std::uint32_t value) { storeU32(room(4), value); }
  void u64(std::uint64_t value) { storeU64(room(8), value); }
  void i32(std::int32_t value) { u32(static_cast<std::uint32_t>(value)); }
  void i64(std::int64_t value) { u64(static_cast<std::uint64_t>(value)); }
  void f64(double value) {
    std::uint64_t bits;
    std::memcpy(&bits, &value, 8);
    u64(bits);
  }
  void bytes(const unsigned char* data, std::size_t count) {
    if (count <= kBufferSize - used_) {
      std::memcpy(buffer_.data() + used_, data, count);
      used_ += count;
      return;
    }
    finish();
    sink_(data, count);
    written_ += count;
  }
  // Integers and floats of 1, 2, 4 or 8 bytes, or blocks of eight corner distances, each stored as its
  // little-endian bit pattern.
  template <typename T>
  void array(const std::vector<T>& values) {
    if constexpr (kBulkCopy || sizeof(T) == 1) {
      bytes(reinterpret_cast<const unsigned char*>(values.data()), sizeof(T) * values.size());
    } else {
      for (const T& value : values) element(value);
    }
  }
  void section(std::uint32_t tag, std::uint64_t length) {
    u32(tag);
    u32(0);
    u64(length);
  }
  void finish() {
    if (used_ == 0) return;
    sink_(buffer_.data(), used_);
    written_ += used_;
    used_ = 0;
  }
  // Bytes passed to the sink so far, and those still buffered.
  std::uint64_t size() const { return written_ + used_; }

 private:
  static constexpr std::size_t kBufferSize = std::size_t(1) << 16;

  unsigned char* room(std::size_t count) {
    if (kBufferSize - used_ < count) finish();
    unsigned char* p = buffer_.data() + used_;
    used_ += count;
    return p;
  }
  template <typename T>
  void element(const T& value) {
    if constexpr (std::is_same_v<T, CornerDistances>) {
      for (std::uint16_t distance : value) element(distance);
    } else if constexpr (sizeof(T) == 2) {
      unsigned char* p = room(2);
      p[0] = static_cast<unsigned char>(value & 0xffu);
      p[1] = static_cast<unsigned char>(value >> 8);
    } else if constexpr (sizeof(T) == 4) {
      std::uint32_t bits;
      std::memcpy(&bits, &value, 4);
      u32(bits);
    } else {
      static_assert(sizeof(T) == 8, "arrays hold bytes, 16-, 32- or 64-bit values, or eight corner distances");
      std::uint64_t bits;
      std::memcpy(&bits, &value, 8);
      u64(bits);
    }
  }
  Sink& sink_;
  std::vector<unsigned char> buffer_;
  std::size_t used_ = 0;
  std::uint64_t written_ = 0;
};

// Reads little-endian values from [data, data + size), throwing a message that names the file and the
// section when a read would run past the end.
class Reader {
 public:
  Reader(const unsigned char* data, std::size_t size, const std::string& context)
      : data_(data), size_(size), context_(context) {}

  std::size_t remaining() const { return size_ - position_; }
  std::size_t position() const { return position_; }

  std::uint32_t u32(const char* what) { return loadU32(take(4, what)); }
  std::uint64_t u64(const char* what) { return loadU64(take(8, what)); }
  std::int32_t i32(const char* what) { return static_cast<std::int32_t>(u32(what)); }
  std::int64_t i64(const char* what) { return static_cast<std::int64_t>(u64(what)); }
  double f64(const char* what) {
    const std::uint64_t bits = u64(what);
    double value;
    std::memcpy(&value, &bits, 8);
    return value;
  }
  // Fills `values` (already sized by a checked count) from the next sizeof(T) * size() bytes, the inverse
  // of Writer::array.
  template <typename T>
  void array(std::vector<T>& values, const char* what) {
    const unsigned char* p = take(sizeof(T) * values.size(), what);
    if constexpr (kBulkCopy || sizeof(T) == 1) {
      if (!values.empty()) std::memcpy(values.data(), p, sizeof(T) * values.size());
    } else {
      for (T& value : values) p = element(value, p);
    }
  }
  const unsigned char* take(std::size_t count, const char* what) {
    if (count > remaining()) {
      fail(std::string("truncated while reading ") + what + " (needs " + std::to_string(count) + " bytes, " +
           std::to_string(remaining()) + " left)");
    }
    const unsigned char* p = data_ + position_;
    position_ += count;
    return p;
  }
  // Reads an element count and checks, before anything is allocated, that that many elements of
  // `element_size` bytes fit in what is left; a corrupt count therefore never triggers a huge allocation.
  std::size_t count(std::size_t element_size, const char* what) {
    const std::uint64_t n = u64(what);
    if (n > remaining() / element_size) {
      fail(std::string(what) + " is " + std::to_string(n) + ", but only " + std::to_string(remaining()) +
           " bytes are left for its " + std::to_string(element_size) + "-byte elements");
    }
    return static_cast<std::size_t>(n);
  }
  [[noreturn]] void fail(const std::string& message) const { throw Error(context_ + ": " + message); }

 private:
  template <typename T>
  static const unsigned char* element(T& value, const unsigned char* p) {
    if constexpr (std::is_same_v<T, CornerDistances>) {
      for (std::uint16_t& distance : value) p = element(distance, p);
      return p;
    } else if constexpr (sizeof(T) == 2) {
      value = static_cast<T>(std::uint16_t(p[0]) | std::uint16_t(p[1]) << 8);
      return p + 2;
    } else if constexpr (sizeof(T) == 4) {
      const std::uint32_t bits = loadU32(p);
      std::memcpy(&value, &bits, 4);
      return p + 4;
    } else {
      static_assert(sizeof(T) == 8, "arrays hold bytes, 16-, 32- or 64-bit values, or eight corner distances");
      const std::uint64_t bits = loadU64(p);
      std::memcpy(&value, &bits, 8);
      return p + 8;
    }
  }

  const unsigned char* data_;
  std::size_t size_;
  std::size_t position_ = 0;
  const std::string& context_;
};

std::string numberText(double value) {
  std::ostringstream text;
  text.precision(17);
  text << value;
  return text.str();
}

std::string dimsText(const std::array<int, 3>& dims) {
  return std::to_string(dims[0]) + " x " + std::to_string(dims[1]) + " x " + std::to_string(dims[2]);
}

// Checks the invariants of CflModel that the query relies on to stay in bounds, to terminate and to be
// exact. Shared by the writer (so a broken model is never written) and the loader (so a broken file is never
// used). The mesh itself is checked by validateMesh. Everything is checked before anything that depends on
// it is read: the root grid before the nodes, the nodes before the leaves, the offsets before the lists.
// The lists' offsets against the sizes of the arrays they index (`ids_name`: what the caller calls its ids).
template <class Fail>
void validateListOffsets(const std::vector<std::uint32_t>& offsets, std::size_t id_count, const char* ids_name,
                         std::size_t bound_count, const Fail& fail) {
  if (offsets.empty()) fail("list_offsets is empty, needs at least its leading 0");
  if (offsets.front() != 0) fail("list_offsets[0] is " + std::to_string(offsets.front()) + ", must be 0");
  if (offsets.back() != id_count) {
    fail("last list offset is " + std::to_string(offsets.back()) + ", but " + ids_name + " has " +
         std::to_string(id_count) + " entries");
  }
  if (bound_count != id_count) {
    fail(std::string(ids_name) + " has " + std::to_string(id_count) + " entries, but list_entry_bounds has " +
         std::to_string(bound_count));
  }
  // Offsets first, all of them: a list's contents are only meaningful once its bounds are.
  for (std::size_t list = 0; list + 1 < offsets.size(); ++list) {
    if (offsets[list + 1] < offsets[list]) {
      fail("list_offsets not increasing: list " + std::to_string(list) + " starts at " + std::to_string(offsets[list]) +
           " and ends at " + std::to_string(offsets[list + 1]));
    }
  }
}

// Every list non-empty, its ids in range and sorted by (entry bound, id). `id_at(list, n)`: entry n's id;
// the offsets have passed validateListOffsets.
template <class IdAt, class Fail>
void validateListContents(const std::vector<std::uint32_t>& offsets, const IdAt& id_at,
                          const std::vector<std::uint8_t>& bounds, std::size_t triangle_count, const Fail& fail) {
  for (std::size_t list = 0; list + 1 < offsets.size(); ++list) {
    const std::uint32_t begin = offsets[list], end = offsets[list + 1];
    if (end == begin) fail("list " + std::to_string(list) + " is empty (every CFL holds at least one triangle)");
    std::int64_t previous = -1;
    int previous_bound = 0;
    for (std::uint32_t i = begin; i < end; ++i) {
      const std::int32_t id = id_at(std::uint32_t(list), i - begin);
      const int bound = bounds[i];
      if (id < 0 || static_cast<std::size_t>(id) >= triangle_count) {
        fail("list " + std::to_string(list) + " holds triangle id " + std::to_string(id) + ", out of range [0, " +
             std::to_string(triangle_count) + ")");
      }
      if (bound < previous_bound || (bound == previous_bound && id <= previous)) {
        fail("list " + std::to_string(list) + " is not sorted by (entry bound, id) (triangle " + std::to_string(id) +
             " with bound " + std::to_string(bound) + " after triangle " + std::to_string(previous) +
             " with bound " + std::to_string(previous_bound) + ")");
      }
      previous = id;
      previous_bound = bound;
    }
  }
}

void validateModelStructure(const CflModel& model, const std::string& context) {
  const auto fail = [&](const std::string& message) { throw Error(context + ": " + message); };
  const RegionTree& tree = model.regions;
  const std::size_t triangle_count = model.geometry.mesh.triangles.size();

  // The root grid.
  if (!tree.origin.allFinite()) fail("regions origin is not finite");
  if (!std::isfinite(tree.root_size) || !(tree.root_size > 0)) {
    fail("regions root_size is " + numberText(tree.root_size) + ", not a finite positive length");
  }
  for (int axis = 0; axis < 3; ++axis) {
    if (tree.root_dims[axis] < 1) {
      fail("regions root_dims[" + std::to_string(axis) + "] is " + std::to_string(tree.root_dims[axis]) +
           ", must be >= 1");
    }
  }
  if (!tree.bounds().max.allFinite()) fail("regions far corner is not finite (root_size times root_dims overflows)");
  if (tree.max_depth < 0 || tree.max_depth > kMaxTreeDepth) {
    fail("regions max_depth is " + std::to_string(tree.max_depth) + ", must be in [0, " +
         std::to_string(kMaxTreeDepth) + "]");
  }
  // A power of two (frexp's mantissa exactly 1/2) in [kFinestCornerDistanceUnit, 1]: the query multiplies
  // by it and relies on the product being exact.
  int unit_exponent = 0;
  if (!(tree.corner_distance_unit >= RegionTree::kFinestCornerDistanceUnit && tree.corner_distance_unit <= 1) ||
      std::frexp(tree.corner_distance_unit, &unit_exponent) != 0.5) {
    fail("regions corner_distance_unit is " + numberText(tree.corner_distance_unit) + ", must be a power of two in [" +
         numberText(RegionTree::kFinestCornerDistanceUnit) + ", 1]");
  }
  if (!std::isfinite(model.padding) || model.padding < 1.0) {
    fail("padding is " + numberText(model.padding) + ", must be a finite factor >= 1");
  }

  // The nodes. Node and leaf indices are 31-bit (the top bit marks a leaf), which also keeps `v + 8` below.
  const std::uint64_t node_count = tree.nodes.size();
  const std::uint64_t leaf_count = tree.leaf_list.size();
  if (node_count >= RegionTree::kLeafBit) {
    fail(std::to_string(node_count) + " nodes, more than 31-bit indices can name");
  }
  if (leaf_count >= RegionTree::kLeafBit) {
    fail(std::to_string(leaf_count) + " leaves, more than 31-bit indices can name");
  }
  // The root cells come first among the nodes, so there must be at least as many nodes as root cells,
  // checked by division so that absurd dims (three ints multiply to 2^93) never overflow; only then is
  // rootCount() safe to call.
  const std::uint64_t d0 = std::uint64_t(tree.root_dims[0]), d1 = std::uint64_t(tree.root_dims[1]),
                      d2 = std::uint64_t(tree.root_dims[2]);
  if (d0 > node_count || d1 > node_count / d0 || d2 > node_count / (d0 * d1)) {
    fail("regions root grid of " + dimsText(tree.root_dims) + " cells, but only " + std::to_string(node_count) +
         " nodes");
  }
  const std::uint64_t root_count = static_cast<std::uint64_t>(tree.rootCount());

  if (tree.leaf_lower_bound.size() != leaf_count || tree.leaf_corner_distance.size() != leaf_count) {
    fail("leaf arrays disagree: leaf_list has " + std::to_string(leaf_count) + " entries, leaf_lower_bound " +
         std::to_string(tree.leaf_lower_bound.size()) + ", leaf_corner_distance " +
         std::to_string(tree.leaf_corner_distance.size()));
  }

  // One pass in index order: children come after their parent, so by the time node n is reached every node
  // that may point to it has been seen, and its depth is known. Pointing only forward rules out cycles (a
  // query walking down the tree always ends); each node being the child of exactly one parent makes it a
  // forest of the root cells (no walk visits a cell twice, no node is dead weight); the depth limit keeps
  // forEachLeafInBox's fixed stack in bounds.
  constexpr std::uint8_t kUnreached = 0xFF;
  std::vector<std::uint8_t> depth(static_cast<std::size_t>(node_count), kUnreached);
  std::vector<std::uint32_t> parent(static_cast<std::size_t>(node_count), 0);
  std::fill(depth.begin(), depth.begin() + static_cast<std::ptrdiff_t>(root_count), std::uint8_t(0));
  std::vector<bool> leaf_seen(static_cast<std::size_t>(leaf_count), false);
  std::vector<std::int64_t> leaves_per_depth;
  for (std::uint64_t n = 0; n < node_count; ++n) {
    const std::uint32_t value = tree.nodes[n];
    if (depth[n] == kUnreached) {
      fail("node " + std::to_string(n) + " is not a root cell and no node points to it as a child");
    }
    const int d = depth[n];
    if (value & RegionTree::kLeafBit) {
      const std::uint32_t leaf = value & ~RegionTree::kLeafBit;
      if (leaf >= leaf_count) {
        fail("node " + std::to_string(n) + " is leaf " + std::to_string(leaf) + ", out of range [0, " +
             std::to_string(leaf_count) + ")");
      }
      if (leaf_seen[leaf]) {
        fail("leaf " + std::to_string(leaf) + " is referenced twice (again by node " + std::to_string(n) + ")");
      }
      leaf_seen[leaf] = true;
      if (leaves_per_depth.size() <= std::size_t(d)) leaves_per_depth.resize(d + 1, 0);
      ++leaves_per_depth[d];
      continue;
    }
    if (value <= n) {
      fail("node " + std::to_string(n) + " points to children at node " + std::to_string(value) +
           ", not after itself (children follow their parent; a node pointing to itself or back would loop)");
    }
    if (value < root_count) {
      fail("node " + std::to_string(n) + " points to children at node " + std::to_string(value) +
           ", a root cell (there are " + std::to_string(root_count) + ")");
    }
    if (std::uint64_t(value) + 8 > node_count) {
      fail("node " + std::to_string(n) + " points to children at nodes " + std::to_string(value) + " to " +
           std::to_string(std::uint64_t(value) + 7) + ", past the " + std::to_string(node_count) + " nodes");
    }
    if (d + 1 > tree.max_depth) {
      fail("node " + std::to_string(n) + " at depth " + std::to_string(d) + " has children at depth " +
           std::to_string(d + 1) + ", deeper than max_depth " + std::to_string(tree.max_depth));
    }
    for (std::uint32_t child = value; child < value + 8; ++child) {
      if (depth[child] != kUnreached) {
        fail("node " + std::to_string(child) + " is the child of two parents, nodes " + std::to_string(parent[child]) +
             " and " + std::to_string(n) + " (a child block is shared)");
      }
      depth[child] = static_cast<std::uint8_t>(d + 1);
      parent[child] = static_cast<std::uint32_t>(n);
    }
  }
  for (std::uint64_t leaf = 0; leaf < leaf_count; ++leaf) {
    if (!leaf_seen[leaf]) fail("leaf " + std::to_string(leaf) + " is referenced by no node");
  }
  // With every node reached and every leaf used once, leaves_per_depth is non-empty when there are leaves;
  // max_depth is documented as the deepest leaf's depth, which the query sizes its margins by.
  const int deepest = static_cast<int>(leaves_per_depth.size()) - 1;
  if (tree.max_depth != deepest) {
    fail("regions max_depth is " + std::to_string(tree.max_depth) + ", but the deepest leaf is at depth " +
         std::to_string(deepest));
  }

  // The lists: their encoding (RegionTree::list_entry_ids), then the ids they decode to.
  const auto& offsets = tree.list_offsets;
  // No list at all is possible when every leaf is one without a list (RegionTree::kNoList).
  if (offsets.empty()) fail("list_offsets is empty, needs at least its leading 0");
  const std::size_t list_count = offsets.size() - 1;
  // Two slots of list_entry_ids per list hold its base (RegionTree::listIdsBegin), one per entry its id.
  if (tree.list_entry_ids.size() < 2 * list_count) {
    fail("list_entry_ids has " + std::to_string(tree.list_entry_ids.size()) + " entries, fewer than the bases of " +
         std::to_string(list_count) + " lists");
  }
  validateListOffsets(offsets, tree.list_entry_ids.size() - 2 * list_count, "list_entry_ids (bases aside)",
                      tree.list_entry_bounds.size(), fail);
  for (std::size_t list = 0; list < list_count; ++list) {
    const std::int32_t base = tree.listBase(std::uint32_t(list));
    if (base < 0 &&
        std::uint64_t(std::uint32_t(~base)) + tree.listLength(std::uint32_t(list)) > tree.list_high_ids.size()) {
      fail("list " + std::to_string(list) + " reads list_high_ids past its " +
           std::to_string(tree.list_high_ids.size()) + " entries");
    }
  }
  validateListContents(offsets, [&](std::uint32_t list, std::uint32_t n) { return tree.listTriangle(list, n); },
                       tree.list_entry_bounds, triangle_count, fail);

  // The leaves.
  std::int64_t without_list = 0;
  for (std::size_t leaf = 0; leaf < leaf_count; ++leaf) {
    if (tree.leaf_list[leaf] == RegionTree::kNoList) {
      ++without_list;
    } else if (tree.leaf_list[leaf] >= list_count) {
      fail("leaf_list of leaf " + std::to_string(leaf) + " is list " + std::to_string(tree.leaf_list[leaf]) +
           ", out of range [0, " + std::to_string(list_count) + ") and not RegionTree::kNoList");
    }
    const float lower = tree.leaf_lower_bound[leaf];
    if (!std::isfinite(lower) || lower < 0) {
      fail("leaf_lower_bound of leaf " + std::to_string(leaf) + " is " + numberText(lower) +
           ", must be finite and >= 0");
    }
  }

  const BuildStatistics& s = model.statistics;
  if (s.voxel_count != std::int64_t(leaf_count)) {
    fail("statistics say " + std::to_string(s.voxel_count) + " leaves, the regions have " + std::to_string(leaf_count));
  }
  if (s.leaves_without_list != without_list) {
    fail("statistics say " + std::to_string(s.leaves_without_list) + " leaves without a list, the regions have " +
         std::to_string(without_list));
  }
  if (s.leaves_per_depth != leaves_per_depth) {
    std::string said, found;
    for (std::int64_t count : s.leaves_per_depth) said += (said.empty() ? "" : " ") + std::to_string(count);
    for (std::int64_t count : leaves_per_depth) found += (found.empty() ? "" : " ") + std::to_string(count);
    fail("statistics say leaves per depth [" + said + "], the regions have [" + found + "]");
  }
  if (s.distinct_lists != std::int64_t(list_count)) {
    fail("statistics say " + std::to_string(s.distinct_lists) + " distinct lists, the regions have " +
         std::to_string(list_count));
  }
  if (s.resolution < 1 || s.longest_list < 0 || s.memory_bytes < 0 || !std::isfinite(s.average_list_length) ||
      s.average_list_length < 0 || !std::isfinite(s.build_seconds) || s.build_seconds < 0) {
    fail("statistics hold a negative or non-finite figure");
  }
}

}  // namespace

namespace detail {

std::uint32_t crc32(const unsigned char* data, std::size_t size) { return crc32Update(0, data, size); }

void resealCflBuffer(unsigned char* data, std::size_t size) {
  if (size < kHeaderSize) return;
  storeU32(data + 24, crc32(data + kHeaderSize, size - kHeaderSize));
  storeU32(data + 28, crc32(data, 28));
}

}  // namespace detail

namespace {

// The payload's size, known before any of it is written because the header, which comes first, holds it.
// Validates the model first, so that nothing is written that the loader would refuse.
std::uint64_t checkedPayloadSize(const CflModel& model) {
  validateMesh(model.geometry.mesh);
  validateModelStructure(model, "cannot save CFL model");
  const TriangleMesh& mesh = model.geometry.mesh;
  const RegionTree& tree = model.regions;
  const std::uint64_t mesh_size = 16 + 24 * mesh.vertices.size() + 12 * mesh.triangles.size();
  const std::uint64_t node_size = 8 + 4 * tree.nodes.size();
  const std::uint64_t leaf_size = 8 + kLeafRecordSize * tree.leaf_list.size();
  // One 4-byte id per entry, whatever RegionTree's encoding in memory; there are as many entries as bounds.
  const std::uint64_t list_size = 16 + 4 * (tree.list_offsets.size() + tree.list_entry_bounds.size());
  const std::uint64_t entry_bounds_size = 8 + tree.list_entry_bounds.size();
  const std::uint64_t statistics_size = kStatisticsFixedSize + 8 * model.statistics.leaves_per_depth.size();
  return 7 * kSectionHeaderSize + mesh_size + kTreeSectionSize + node_size + leaf_size + list_size +
         entry_bounds_size + statistics_size;
}

// Writes the payload's sections in file order (checkedPayloadSize sizes them the same way).
template <typename Sink>
void writePayload(const CflModel& model, Writer<Sink>& out) {
  const TriangleMesh& mesh = model.geometry.mesh;
  const RegionTree& tree = model.regions;
  const BuildStatistics& s = model.statistics;

  out.section(kTagMesh, 16 + 24 * mesh.vertices.size() + 12 * mesh.triangles.size());
  out.u64(mesh.vertices.size());
  out.u64(mesh.triangles.size());
  for (const Eigen::Vector3d& p : mesh.vertices) {
    for (int axis = 0; axis < 3; ++axis) out.f64(p[axis]);
  }
  for (const auto& triangle : mesh.triangles) {
    for (int index : triangle) out.i32(index);
  }

  out.section(kTagTree, kTreeSectionSize);
  for (int axis = 0; axis < 3; ++axis) out.f64(tree.origin[axis]);
  out.f64(tree.root_size);
  for (int axis = 0; axis < 3; ++axis) out.i32(tree.root_dims[axis]);
  out.i32(tree.max_depth);
  out.f64(model.padding);
  out.u32(model.topology_culling ? 1u : 0u);
  out.f64(tree.corner_distance_unit);

  out.section(kTagNodes, 8 + 4 * tree.nodes.size());
  out.u64(tree.nodes.size());
  out.array(tree.nodes);

  out.section(kTagLeaves, 8 + kLeafRecordSize * tree.leaf_list.size());
  out.u64(tree.leaf_list.size());
  out.array(tree.leaf_list);
  out.array(tree.leaf_lower_bound);
  out.array(tree.leaf_corner_distance);

  // The ids are decoded list by list straight into the output, never into an array of them all.
  const std::uint64_t entry_count = tree.list_entry_bounds.size();
  out.section(kTagList, 16 + 4 * (tree.list_offsets.size() + entry_count));
  out.u64(tree.list_offsets.size());
  out.u64(entry_count);
  out.array(tree.list_offsets);
  for (std::uint32_t list = 0; list < tree.listCount(); ++list) {
    tree.forEachListTriangle(list, tree.listLength(list), [&](std::ptrdiff_t, std::int32_t id) { out.i32(id); });
  }

  out.section(kTagEntryBounds, 8 + entry_count);
  out.u64(entry_count);
  out.array(tree.list_entry_bounds);

  out.section(kTagStatistics, kStatisticsFixedSize + 8 * s.leaves_per_depth.size());
  out.i64(s.resolution);
  out.i64(s.voxel_count);
  out.i64(s.leaves_without_list);
  out.f64(s.average_list_length);
  out.i64(s.longest_list);
  out.i64(s.distinct_lists);
  out.i64(s.memory_bytes);
  out.f64(s.build_seconds);
  out.u32(s.coarsened ? 1u : 0u);
  out.u64(s.leaves_per_depth.size());
  out.array(s.leaves_per_depth);
  out.finish();
}

void checkWrittenSize(std::uint64_t written, std::uint64_t payload_size) {
  if (written != payload_size) throw std::logic_error("CFL file writer: size bookkeeping is off");
}

std::array<unsigned char, kHeaderSize> fileHeader(std::uint64_t payload_size, std::uint32_t payload_crc) {
  std::array<unsigned char, kHeaderSize> header{};
  std::memcpy(header.data(), kMagic.data(), kMagic.size());
  storeU32(header.data() + 8, kEndianMarker);
  storeU32(header.data() + 12, kCflFileVersion);
  storeU64(header.data() + 16, payload_size);
  storeU32(header.data() + 24, payload_crc);
  storeU32(header.data() + 28, detail::crc32(header.data(), 28));
  return header;
}

// Writes bytes to `stream`, counting them into `written`; when the stream fails, says how far of `total`
// it got.
auto streamSink(std::ostream& stream, std::uint64_t& written, std::uint64_t total) {
  return [&stream, &written, total](const unsigned char* data, std::size_t count) {
    if (!stream.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(count))) {
      throw Error("writing a CFL model: the stream failed after " + std::to_string(written) + " of " +
                  std::to_string(total) + " bytes");
    }
    written += count;
  };
}

// writeCflModel once the model is validated and its payload sized. The header's payload checksum precedes
// the payload, so a first pass over the model computes it without writing anything; the second writes the
// file once, in order, so the stream is never sought (pipes work) and no copy of the file is held.
void writeValidatedCflModel(const CflModel& model, std::uint64_t payload_size, std::ostream& stream) {
  std::uint32_t payload_crc = 0;
  const auto checksum = [&](const unsigned char* data, std::size_t count) {
    payload_crc = crc32Update(payload_crc, data, count);
  };
  Writer<decltype(checksum)> checksum_pass(checksum);
  writePayload(model, checksum_pass);
  checkWrittenSize(checksum_pass.size(), payload_size);

  std::uint64_t written = 0;
  const auto put = streamSink(stream, written, kHeaderSize + payload_size);
  const std::array<unsigned char, kHeaderSize> header = fileHeader(payload_size, payload_crc);
  put(header.data(), header.size());
  Writer<decltype(put)> out(put);
  writePayload(model, out);
  checkWrittenSize(out.size(), payload_size);
}

// writeValidatedCflModel for a file, which can be sought: the payload is written once and checksummed on
// its way out, and the header, written first with a zero checksum, is rewritten once the checksum is known
// (the same bytes, one pass over the model fewer).
void writeValidatedCflFile(const CflModel& model, std::uint64_t payload_size, std::ofstream& file) {
  std::uint64_t written = 0;
  std::uint32_t payload_crc = 0;
  const auto put = streamSink(file, written, kHeaderSize + payload_size);
  std::array<unsigned char, kHeaderSize> header = fileHeader(payload_size, 0);
  put(header.data(), header.size());
  const auto checksummed = [&](const unsigned char* data, std::size_t count) {
    payload_crc = crc32Update(payload_crc, data, count);
    put(data, count);
  };
  Writer<decltype(checksummed)> out(checksummed);
  writePayload(model, out);
  checkWrittenSize(out.size(), payload_size);
  header = fileHeader(payload_size, payload_crc);
  if (!file.seekp(0)) throw Error("writing a CFL model: cannot seek back to the header");
  written = 0;
  put(header.data(), header.size());
}

}  // namespace

std::vector<unsigned char> serializeCflModel(const CflModel& model) {
  const std::uint64_t payload_size = checkedPayloadSize(model);
  std::vector<unsigned char> bytes;
  bytes.reserve(kHeaderSize + payload_size);
  const auto append = [&](const unsigned char* data, std::size_t count) {
    bytes.insert(bytes.end(), data, data + count);
  };
  const std::array<unsigned char, kHeaderSize> header = fileHeader(payload_size, 0);
  append(header.data(), header.size());
  Writer<decltype(append)> out(append);
  writePayload(model, out);
  checkWrittenSize(out.size(), payload_size);
  detail::resealCflBuffer(bytes.data(), bytes.size());  // the payload checksum, now that the payload is here
  return bytes;
}

void writeCflModel(const CflModel& model, std::ostream& stream) {
  writeValidatedCflModel(model, checkedPayloadSize(model), stream);
}

namespace {

// Checks the header from its first `available` bytes (at most kHeaderSize are read) of a file of
// `total_size` bytes and returns the payload size. Lets loadCflModel refuse another kind of file, or a file
// whose size does not match its header, before reading it all.
std::uint64_t checkHeader(const unsigned char* data, std::size_t available, std::uint64_t total_size,
                          const std::string& name) {
  const auto fail = [&](const std::string& message) { throw Error(name + ": " + message); };
  // In the order that gives the most useful message: another kind of file first, then a file from an
  // earlier cfl, a foreign writer or a later version (whose header may differ past this point), then
  // corruption.
  if (available < kMagic.size() || std::memcmp(data, kMagic.data(), kMagic.size()) != 0) {
    fail("not a CFL model file (first bytes: " + hexBytes(data, std::min<std::size_t>(available, 8)) +
         "; expected " + hexBytes(kMagic.data(), kMagic.size()) + ")");
  }
  if (available < kHeaderSize) {
    fail("truncated: " + std::to_string(total_size) + " bytes, shorter than the " + std::to_string(kHeaderSize) +
         "-byte header");
  }
  const std::uint32_t marker = loadU32(data + 8);
  if (marker != kEndianMarker) {
    if (marker == 0x04030201u) {
      fail("written in big-endian byte order (marker bytes 01 02 03 04); files are little-endian");
    }
    fail("bad endianness marker (bytes " + hexBytes(data + 8, 4) + ", expected 04 03 02 01)");
  }
  const std::uint32_t version = loadU32(data + 12);
  // Versions 1 and 2 stored a uniform grid, which the regions no longer are; the build is the only way
  // from one to the other, so no loader for them is kept.
  if (version == 1 || version == 2) {
    fail("a version-" + std::to_string(version) +
         " CFL file (uniform grid) from an earlier cfl: rebuild it with `cfl build`");
  }
  if (version == 3) {
    fail("a version-3 CFL file (float corner distances) from an earlier cfl: rebuild it with `cfl build`");
  }
  if (version != kCflFileVersion) {
    fail("format version " + std::to_string(version) + " is not supported (this library reads version " +
         std::to_string(kCflFileVersion) + ")");
  }
  const std::uint32_t header_crc = detail::crc32(data, 28);
  if (header_crc != loadU32(data + 28)) {
    fail("header checksum mismatch (CRC-32 is " + hexU32(header_crc) + ", header says " + hexU32(loadU32(data + 28)) +
         "): the file is corrupt");
  }
  const std::uint64_t payload_size = loadU64(data + 16);
  if (payload_size > total_size - kHeaderSize) {
    fail("truncated: " + std::to_string(total_size) + " bytes, but the header says " + std::to_string(kHeaderSize) +
         " + " + std::to_string(payload_size));
  }
  if (payload_size < total_size - kHeaderSize) {
    fail(std::to_string(total_size - kHeaderSize - payload_size) + " unexpected bytes after the payload of " +
         std::to_string(payload_size) + " bytes");
  }
  return payload_size;
}

}  // namespace

CflModel deserializeCflModel(const unsigned char* data, std::size_t size, const std::string& name_for_errors) {
  const std::string& name = name_for_errors;
  const auto fail = [&](const std::string& message) { throw Error(name + ": " + message); };
  if (data == nullptr && size != 0) fail("no data");
  const std::uint64_t payload_size = checkHeader(data, size, size, name);
  const std::uint32_t payload_crc = detail::crc32(data + kHeaderSize, payload_size);
  if (payload_crc != loadU32(data + 24)) {
    fail("checksum mismatch (payload CRC-32 is " + hexU32(payload_crc) + ", header says " +
         hexU32(loadU32(data + 24)) + "): the file is corrupt");
  }

  CflModel model;
  RegionTree& tree = model.regions;
  std::vector<std::int32_t> list_triangles;  // as the file stores them; encoded once read
  TriangleMesh mesh;
  bool seen_mesh = false, seen_tree = false, seen_nodes = false, seen_leaves = false, seen_list = false,
       seen_entry_bounds = false, seen_statistics = false;
  Reader payload(data + kHeaderSize, payload_size, name);
  while (payload.remaining() > 0) {
    const std::size_t section_offset = kHeaderSize + payload.position();
    const std::uint32_t tag = payload.u32("section tag");
    const std::uint32_t reserved = payload.u32("section header");
    const std::uint64_t length = payload.u64("section length");
    const std::string context = name + ": section " + tagName(tag) + " at byte " + std::to_string(section_offset);
    if (reserved != 0) throw Error(context + ": reserved field is " + std::to_string(reserved) + ", must be 0");
    if (length > payload.remaining()) {
      throw Error(context + ": length " + std::to_string(length) + " runs past the end of the file (" +
                  std::to_string(payload.remaining()) + " bytes left)");
    }
    Reader in(payload.take(static_cast<std::size_t>(length), "section"), static_cast<std::size_t>(length), context);
    const auto once = [&](bool& seen) {
      if (seen) in.fail("appears twice");
      seen = true;
    };

    if (tag == kTagMesh) {
      once(seen_mesh);
      const std::size_t vertex_count = in.count(24, "vertex count");
      const std::size_t triangle_count = in.count(12, "triangle count");
      if (vertex_count > std::size_t(std::numeric_limits<std::int32_t>::max()) ||
          triangle_count > std::size_t(std::numeric_limits<std::int32_t>::max())) {
        in.fail("more vertices or triangles than 32-bit ids can name");
      }
      mesh.vertices.resize(vertex_count);
      for (auto& p : mesh.vertices) {
        for (int axis = 0; axis < 3; ++axis) p[axis] = in.f64("vertex");
      }
      mesh.triangles.resize(triangle_count);
      for (auto& triangle : mesh.triangles) {
        for (int& index : triangle) index = in.i32("triangle");
      }
    } else if (tag == kTagTree) {
      once(seen_tree);
      for (int axis = 0; axis < 3; ++axis) tree.origin[axis] = in.f64("origin");
      tree.root_size = in.f64("root_size");
      for (int axis = 0; axis < 3; ++axis) tree.root_dims[axis] = in.i32("root_dims");
      tree.max_depth = in.i32("max_depth");
      model.padding = in.f64("padding");
      const std::uint32_t flags = in.u32("flags");
      if (flags > 1u) in.fail("unknown flags " + hexU32(flags));
      model.topology_culling = (flags & 1u) != 0;
      tree.corner_distance_unit = in.f64("corner_distance_unit");
    } else if (tag == kTagNodes) {
      once(seen_nodes);
      tree.nodes.resize(in.count(4, "node count"));
      in.array(tree.nodes, "nodes");
    } else if (tag == kTagLeaves) {
      once(seen_leaves);
      const std::size_t leaf_count = in.count(kLeafRecordSize, "leaf count");
      tree.leaf_list.resize(leaf_count);
      in.array(tree.leaf_list, "leaf_list");
      tree.leaf_lower_bound.resize(leaf_count);
      in.array(tree.leaf_lower_bound, "leaf_lower_bound");
      tree.leaf_corner_distance.resize(leaf_count);
      in.array(tree.leaf_corner_distance, "leaf_corner_distance");
    } else if (tag == kTagList) {
      once(seen_list);
      const std::size_t offset_count = in.count(4, "list_offsets size");
      const std::size_t id_count = in.count(4, "list_triangles size");
      if (in.remaining() / 4 < offset_count || in.remaining() / 4 - offset_count < id_count) {
        in.fail("array sizes " + std::to_string(offset_count) + " + " + std::to_string(id_count) +
                " do not fit in the section");
      }
      tree.list_offsets.resize(offset_count);
      in.array(tree.list_offsets, "list_offsets");
      list_triangles.resize(id_count);
      in.array(list_triangles, "list_triangles");
    } else if (tag == kTagEntryBounds) {
      once(seen_entry_bounds);
      tree.list_entry_bounds.resize(in.count(1, "list_entry_bounds size"));
      in.array(tree.list_entry_bounds, "list_entry_bounds");
    } else if (tag == kTagStatistics) {
      once(seen_statistics);
      BuildStatistics& s = model.statistics;
      const std::int64_t resolution = in.i64("resolution");
      if (resolution < 0 || resolution > std::numeric_limits<int>::max()) in.fail("resolution out of range");
      s.resolution = static_cast<int>(resolution);
      s.voxel_count = in.i64("voxel count");
      s.leaves_without_list = in.i64("leaves without a list");
      s.average_list_length = in.f64("average list length");
      s.longest_list = in.i64("longest list");
      s.distinct_lists = in.i64("distinct lists");
      s.memory_bytes = in.i64("memory bytes");
      s.build_seconds = in.f64("build seconds");
      const std::uint32_t flags = in.u32("statistics flags");
      if (flags > 1u) in.fail("unknown statistics flags " + hexU32(flags));
      s.coarsened = (flags & 1u) != 0;
      s.leaves_per_depth.resize(in.count(8, "leaves_per_depth size"));
      in.array(s.leaves_per_depth, "leaves_per_depth");
    } else {
      continue;  // A section added by a later writer of the same version: not needed to answer queries.
    }
    if (in.remaining() != 0) in.fail(std::to_string(in.remaining()) + " unexpected bytes at the end of the section");
  }
  const char* missing = !seen_mesh ? "MESH" : !seen_tree ? "TREE" : !seen_nodes ? "NODE" : !seen_leaves ? "LEAF"
                        : !seen_list ? "LIST" : !seen_entry_bounds ? "LBND" : !seen_statistics ? "STAT" : nullptr;
  if (missing) fail(std::string("required section ") + missing + " is missing");

  try {
    model.geometry = makeMeshModel(std::move(mesh));
  } catch (const Error& error) {
    fail(std::string("MESH section: ") + error.what());
  }
  // The lists as stored, checked before RegionTree::appendList encodes them (it needs ids >= 0).
  {
    validateListOffsets(tree.list_offsets, list_triangles.size(), "list_triangles", tree.list_entry_bounds.size(),
                        fail);
    validateListContents(
        tree.list_offsets,
        [&](std::uint32_t list, std::uint32_t n) { return list_triangles[tree.list_offsets[list] + n]; },
        tree.list_entry_bounds, model.geometry.mesh.triangles.size(), fail);
    const std::vector<std::uint32_t> offsets = std::move(tree.list_offsets);
    const std::vector<std::uint8_t> bounds = std::move(tree.list_entry_bounds);
    tree.list_offsets.assign(1, 0);
    tree.list_entry_bounds.clear();
    for (std::size_t list = 0; list + 1 < offsets.size(); ++list) {
      tree.appendList(list_triangles.data() + offsets[list], bounds.data() + offsets[list],
                      offsets[list + 1] - offsets[list]);
    }
    tree.list_offsets.shrink_to_fit();
    tree.list_entry_ids.shrink_to_fit();
    tree.list_high_ids.shrink_to_fit();
  }
  model.sign = analyzeMeshSign(model.geometry);
  validateModelStructure(model, name);
  return model;
}

void saveCflModel(const CflModel& model, const std::string& path) {
  // Validated before any file is created, so that a model the loader would refuse leaves no trace.
  const std::uint64_t payload_size = checkedPayloadSize(model);
  const std::uint64_t file_size = kHeaderSize + payload_size;
  // A unique temporary name per process, thread and call, so concurrent writers never share one.
  static std::atomic<unsigned> counter{0};
  std::ostringstream temporary;
  temporary << path << ".tmp";
#if defined(__unix__) || defined(__APPLE__)
  temporary << "." << ::getpid();
#endif
  temporary << "." << std::hash<std::thread::id>()(std::this_thread::get_id()) % 1000000 << "." << counter++;
  const std::string temporary_path = temporary.str();
  {
    std::ofstream file(temporary_path, std::ios::binary | std::ios::trunc);
    if (!file) throw Error(path + ": cannot open " + temporary_path + " for writing: " + std::strerror(errno));
    bool failed = false;
    try {
      writeValidatedCflFile(model, payload_size, file);
      file.close();
      failed = !file;
    } catch (const Error&) {
      failed = true;  // a write failed (the model is valid by now); errno says why
    } catch (...) {
      file.close();
      std::remove(temporary_path.c_str());
      throw;
    }
    if (failed) {
      const std::string reason = std::strerror(errno);
      file.close();
      std::remove(temporary_path.c_str());
      throw Error(path + ": writing " + std::to_string(file_size) + " bytes failed: " + reason);
    }
  }
  if (std::rename(temporary_path.c_str(), path.c_str()) != 0) {
    const std::string reason = std::strerror(errno);
    std::remove(temporary_path.c_str());
    throw Error(path + ": cannot replace the file: " + reason);
  }
}

CflModel loadCflModel(const std::string& path) {
  std::error_code error;
  const auto status = std::filesystem::status(path, error);
  if (error) throw Error(path + ": cannot open for reading: " + error.message());
  if (!std::filesystem::is_regular_file(status)) throw Error(path + ": not a regular file");
  const std::uint64_t size = std::filesystem::file_size(path, error);
  if (error) throw Error(path + ": cannot determine the file size: " + error.message());
  std::ifstream file(path, std::ios::binary);
  if (!file) throw Error(path + ": cannot open for reading: " + std::strerror(errno));

  // The header alone first: another kind of file, or one whose size disagrees with its header, is refused
  // before the whole file is read into memory.
  unsigned char header[kHeaderSize] = {};
  file.read(reinterpret_cast<char*>(header), static_cast<std::streamsize>(std::min<std::uint64_t>(size, kHeaderSize)));
  checkHeader(header, static_cast<std::size_t>(file.gcount()), size, path);

  std::vector<unsigned char> bytes(static_cast<std::size_t>(size));
  file.seekg(0);
  file.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  if (file.gcount() != static_cast<std::streamsize>(bytes.size())) {
    throw Error(path + ": read " + std::to_string(file.gcount()) + " of " + std::to_string(bytes.size()) +
                " bytes (file changed while reading?)");
  }
  return deserializeCflModel(bytes.data(), bytes.size(), path);
}

}  // namespace cfl
