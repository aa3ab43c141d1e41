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
#include <sstream>
#include <thread>

#if defined(__unix__) || defined(__APPLE__)
#include <unistd.h>
#endif

namespace cfl {
namespace {

static_assert(std::numeric_limits<double>::is_iec559 && sizeof(double) == 8,
              "the file stores doubles as IEEE-754 binary64 bit patterns");

// On a little-endian host the file's arrays have the memory layout of the vectors, so they are copied in
// bulk (about 3x faster to load); elsewhere, or when built with -DCFL_FILE_BULK_COPY=0 (as the sanitizer CI
// build is, so that both paths are tested), every value goes through the byte-by-byte conversions.
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
constexpr std::uint32_t kTagGrid = makeTag("GRID");
constexpr std::uint32_t kTagList = makeTag("LIST");
constexpr std::uint32_t kTagBounds = makeTag("BNDS");
constexpr std::uint32_t kTagStatistics = makeTag("STAT");
constexpr std::uint32_t kTagEntryBounds = makeTag("LBND");

constexpr std::size_t kGridSectionSize = 3 * 8 + 8 + 3 * 4 + 8 + 4;
constexpr std::size_t kStatisticsSectionSize = 7 * 8;

// Slicing-by-8 tables: table[0] is the classic byte-at-a-time table, table[k][b] the CRC of byte b followed
// by k zero bytes. Eight bytes per step runs at a few GB/s, so the checksum costs little next to parsing.
using CrcTables = std::array<std::array<std::uint32_t, 256>, 8>;
constexpr CrcTables makeCrcTables() {
  CrcTables tables{};
  for (std::uint32_t b = 0; b < 256; ++b) {
    std::uint32_t crc = b;
    for (int bit = 0; bit < 8; ++bit) crc = (crc & 1u) ? (crc >> 1) ^ 0xEDB88320u : crc >> 1;
    tables[0][b] = crc;
  }
  for (std::uint32_t b = 0; b < 256; ++b) {
    for (int k = 1; k < 8; ++k) tables[k][b] = (tables[k - 1][b] >> 8) ^ tables[0][tables[k - 1][b] & 0xFFu];
  }
  return tables;
}
constexpr CrcTables kCrcTables = makeCrcTables();

std::uint32_t loadU32(const unsigned char* p) {
  return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 | std::uint32_t(p[3]) << 24;
}
std::uint64_t loadU64(const unsigned char* p) { return std::uint64_t(loadU32(p)) | std::uint64_t(loadU32(p + 4)) << 32; }
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

// Appends little-endian values to a buffer whose final size is known in advance.
class Writer {
 public:
  explicit Writer(std::size_t capacity) { bytes_.reserve(capacity); }
  void u32(std::uint32_t value) {
    unsigned char p[4];
    storeU32(p, value);
    bytes_.insert(bytes_.end(), p, p + 4);
  }
  void u64(std::uint64_t value) {
    unsigned char p[8];
    storeU64(p, value);
    bytes_.insert(bytes_.end(), p, p + 8);
  }
  void i32(std::int32_t value) { u32(static_cast<std::uint32_t>(value)); }
  void i64(std::int64_t value) { u64(static_cast<std::uint64_t>(value)); }
  void f64(double value) {
    std::uint64_t bits;
    std::memcpy(&bits, &value, 8);
    u64(bits);
  }
  template <typename T>
  void array(const std::vector<T>& values) {
    static_assert(sizeof(T) == 1 || sizeof(T) == 4 || sizeof(T) == 8, "arrays hold bytes, 32-bit integers or doubles");
    if constexpr (kBulkCopy || sizeof(T) == 1) {
      const auto* p = reinterpret_cast<const unsigned char*>(values.data());
      bytes_.insert(bytes_.end(), p, p + sizeof(T) * values.size());
    } else if constexpr (sizeof(T) == 4) {
      for (T value : values) u32(static_cast<std::uint32_t>(value));
    } else {
      for (double value : values) f64(value);
    }
  }
  void section(std::uint32_t tag, std::uint64_t length) {
    u32(tag);
    u32(0);
    u64(length);
  }
  std::vector<unsigned char>& bytes() { return bytes_; }

 private:
  std::vector<unsigned char> bytes_;
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
  // Fills `values` (already sized by a checked count) from the next sizeof(T) * size() bytes.
  template <typename T>
  void array(std::vector<T>& values, const char* what) {
    static_assert(sizeof(T) == 1 || sizeof(T) == 4 || sizeof(T) == 8, "arrays hold bytes, 32-bit integers or doubles");
    const unsigned char* p = take(sizeof(T) * values.size(), what);
    if constexpr (kBulkCopy || sizeof(T) == 1) {
      if (!values.empty()) std::memcpy(values.data(), p, sizeof(T) * values.size());
    } else if constexpr (sizeof(T) == 4) {
      for (T& value : values) value = static_cast<T>(loadU32(p)), p += 4;
    } else {
      for (double& value : values) {
        const std::uint64_t bits = loadU64(p);
        std::memcpy(&value, &bits, 8);
        p += 8;
      }
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
  const unsigned char* data_;
  std::size_t size_;
  std::size_t position_ = 0;
  const std::string& context_;
};

std::string finiteError(const char* what, std::size_t index, double value) {
  std::ostringstream message;
  message << what << " " << index << " is " << value;
  return message.str();
}

// Checks the invariants of CflModel that the query relies on to stay in bounds and exact. Shared by the
// writer (so a broken model is never written) and the loader (so a broken file is never used). The mesh
// itself is checked by validateMesh.
void validateModelStructure(const CflModel& model, const std::string& context) {
  const auto fail = [&](const std::string& message) { throw Error(context + ": " + message); };
  const VoxelGrid& grid = model.grid;
  const std::size_t triangle_count = model.geometry.mesh.triangles.size();

  if (!grid.origin.allFinite()) fail("grid origin is not finite");
  if (!std::isfinite(grid.voxel_size) || !(grid.voxel_size > 0)) {
    fail("grid voxel size is " + std::to_string(grid.voxel_size) + ", not a finite positive length");
  }
  for (int axis = 0; axis < 3; ++axis) {
    // INT_MAX is out too: VoxelGrid::cornerCount adds 1 to each dim in int arithmetic.
    if (grid.dims[axis] < 1 || grid.dims[axis] == std::numeric_limits<int>::max()) {
      fail("grid dims[" + std::to_string(axis) + "] is " + std::to_string(grid.dims[axis]) + ", must be >= 1 and < 2^31 - 1");
    }
  }
  // The dims must multiply to voxel_list's size, checked by division so that absurd dims (three ints
  // multiply to 2^93) never overflow; only then are VoxelGrid's own count functions safe to call.
  const std::uint64_t listed = model.voxel_list.size();
  const std::uint64_t d0 = std::uint64_t(grid.dims[0]), d1 = std::uint64_t(grid.dims[1]), d2 = std::uint64_t(grid.dims[2]);
  if (listed > std::numeric_limits<std::uint32_t>::max() || d0 > listed || d1 > listed / d0 ||
      d2 > listed / (d0 * d1) || d0 * d1 * d2 != listed) {
    fail("grid of " + std::to_string(grid.dims[0]) + " x " + std::to_string(grid.dims[1]) + " x " +
         std::to_string(grid.dims[2]) + " voxels, but voxel_list has " + std::to_string(listed) + " entries");
  }
  const std::int64_t voxel_count = grid.voxelCount();
  if (!grid.bounds().max.allFinite()) fail("grid far corner is not finite (voxel size times dims overflows)");
  if (!std::isfinite(model.padding) || model.padding < 1.0) {
    fail("padding is " + std::to_string(model.padding) + ", must be a finite factor >= 1");
  }

  if (static_cast<std::int64_t>(model.voxel_lower_bound.size()) != voxel_count) {
    fail("grid has " + std::to_string(voxel_count) + " voxels, but voxel_lower_bound has " +
         std::to_string(model.voxel_lower_bound.size()) + " entries");
  }
  if (static_cast<std::int64_t>(model.corner_distance.size()) != grid.cornerCount()) {
    fail("grid has " + std::to_string(grid.cornerCount()) + " corners, but corner_distance has " +
         std::to_string(model.corner_distance.size()) + " entries");
  }

  const auto& offsets = model.list_offsets;
  if (offsets.size() < 2) fail("list_offsets has " + std::to_string(offsets.size()) + " entries, needs at least 2");
  if (offsets.front() != 0) fail("list_offsets[0] is " + std::to_string(offsets.front()) + ", must be 0");
  if (offsets.back() != model.list_triangles.size()) {
    fail("last list offset is " + std::to_string(offsets.back()) + ", but list_triangles has " +
         std::to_string(model.list_triangles.size()) + " entries");
  }
  if (model.list_entry_bounds.size() != model.list_triangles.size()) {
    fail("list_triangles has " + std::to_string(model.list_triangles.size()) + " entries, but list_entry_bounds has " +
         std::to_string(model.list_entry_bounds.size()));
  }
  const std::size_t list_count = offsets.size() - 1;
  // Offsets first, all of them: a list's contents are only meaningful once its bounds are.
  for (std::size_t list = 0; list < list_count; ++list) {
    if (offsets[list + 1] < offsets[list]) {
      fail("list_offsets not increasing: list " + std::to_string(list) + " starts at " + std::to_string(offsets[list]) +
           " and ends at " + std::to_string(offsets[list + 1]));
    }
  }
  for (std::size_t list = 0; list < list_count; ++list) {
    const std::uint32_t begin = offsets[list], end = offsets[list + 1];
    if (end == begin) fail("list " + std::to_string(list) + " is empty (every CFL holds at least one triangle)");
    std::int64_t previous = -1;
    int previous_bound = 0;
    for (std::uint32_t i = begin; i < end; ++i) {
      const std::int32_t id = model.list_triangles[i];
      const int bound = model.list_entry_bounds[i];
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
  for (std::size_t v = 0; v < model.voxel_list.size(); ++v) {
    if (model.voxel_list[v] >= list_count) {
      fail("voxel " + std::to_string(v) + " refers to list " + std::to_string(model.voxel_list[v]) +
           ", out of range [0, " + std::to_string(list_count) + ")");
    }
  }
  for (std::size_t v = 0; v < model.voxel_lower_bound.size(); ++v) {
    const double value = model.voxel_lower_bound[v];
    if (!std::isfinite(value) || value < 0) fail(finiteError("voxel_lower_bound of voxel", v, value) + ", must be finite and >= 0");
  }
  for (std::size_t c = 0; c < model.corner_distance.size(); ++c) {
    const double value = model.corner_distance[c];
    if (!std::isfinite(value) || value < 0) fail(finiteError("corner_distance of corner", c, value) + ", must be finite and >= 0");
  }

  const BuildStatistics& s = model.statistics;
  if (s.voxel_count != voxel_count) {
    fail("statistics say " + std::to_string(s.voxel_count) + " voxels, the grid has " + std::to_string(voxel_count));
  }
  if (s.resolution < 1 || s.longest_list < 0 || s.distinct_lists < 0 || s.memory_bytes < 0 ||
      !std::isfinite(s.average_list_length) || s.average_list_length < 0 || !std::isfinite(s.build_seconds) ||
      s.build_seconds < 0) {
    fail("statistics hold a negative or non-finite figure");
  }
}

}  // namespace

namespace detail {

std::uint32_t crc32(const unsigned char* data, std::size_t size) {
  std::uint32_t crc = 0xFFFFFFFFu;
  const auto& t = kCrcTables;
  while (size >= 8) {
    const std::uint32_t low = loadU32(data) ^ crc;
    const std::uint32_t high = loadU32(data + 4);
    crc = t[7][low & 0xFF] ^ t[6][(low >> 8) & 0xFF] ^ t[5][(low >> 16) & 0xFF] ^ t[4][low >> 24] ^
          t[3][high & 0xFF] ^ t[2][(high >> 8) & 0xFF] ^ t[1][(high >> 16) & 0xFF] ^ t[0][high >> 24];
    data += 8;
    size -= 8;
  }
  while (size-- > 0) crc = (crc >> 8) ^ t[0][(crc ^ *data++) & 0xFF];
  return crc ^ 0xFFFFFFFFu;
}

void resealCflBuffer(unsigned char* data, std::size_t size) {
  if (size < kHeaderSize) return;
  storeU32(data + 24, crc32(data + kHeaderSize, size - kHeaderSize));
  storeU32(data + 28, crc32(data, 28));
}

}  // namespace detail

std::vector<unsigned char> serializeCflModel(const CflModel& model) {
  validateMesh(model.geometry.mesh);
  validateModelStructure(model, "cannot save CFL model");
  const TriangleMesh& mesh = model.geometry.mesh;

  const std::uint64_t mesh_size = 16 + 24 * mesh.vertices.size() + 12 * mesh.triangles.size();
  const std::uint64_t list_size =
      24 + 4 * (model.voxel_list.size() + model.list_offsets.size() + model.list_triangles.size());
  const std::uint64_t bounds_size = 16 + 8 * (model.voxel_lower_bound.size() + model.corner_distance.size());
  const std::uint64_t entry_bounds_size = 8 + model.list_entry_bounds.size();
  const std::uint64_t payload_size = 6 * kSectionHeaderSize + mesh_size + kGridSectionSize + list_size +
                                     entry_bounds_size + bounds_size + kStatisticsSectionSize;

  Writer out(kHeaderSize + payload_size);
  auto& bytes = out.bytes();
  bytes.insert(bytes.end(), kMagic.begin(), kMagic.end());
  out.u32(kEndianMarker);
  out.u32(kCflFileVersion);
  out.u64(payload_size);
  out.u32(0);  // Both checksums are filled in once the payload is written.
  out.u32(0);

  out.section(kTagMesh, mesh_size);
  out.u64(mesh.vertices.size());
  out.u64(mesh.triangles.size());
  for (const Eigen::Vector3d& p : mesh.vertices) {
    for (int axis = 0; axis < 3; ++axis) out.f64(p[axis]);
  }
  for (const auto& triangle : mesh.triangles) {
    for (int index : triangle) out.i32(index);
  }

  out.section(kTagGrid, kGridSectionSize);
  for (int axis = 0; axis < 3; ++axis) out.f64(model.grid.origin[axis]);
  out.f64(model.grid.voxel_size);
  for (int axis = 0; axis < 3; ++axis) out.i32(model.grid.dims[axis]);
  out.f64(model.padding);
  out.u32(model.topology_culling ? 1u : 0u);

  out.section(kTagList, list_size);
  out.u64(model.voxel_list.size());
  out.u64(model.list_offsets.size());
  out.u64(model.list_triangles.size());
  out.array(model.voxel_list);
  out.array(model.list_offsets);
  out.array(model.list_triangles);

  out.section(kTagEntryBounds, entry_bounds_size);
  out.u64(model.list_entry_bounds.size());
  out.array(model.list_entry_bounds);

  out.section(kTagBounds, bounds_size);
  out.u64(model.voxel_lower_bound.size());
  out.u64(model.corner_distance.size());
  out.array(model.voxel_lower_bound);
  out.array(model.corner_distance);

  const BuildStatistics& s = model.statistics;
  out.section(kTagStatistics, kStatisticsSectionSize);
  out.i64(s.resolution);
  out.i64(s.voxel_count);
  out.f64(s.average_list_length);
  out.i64(s.longest_list);
  out.i64(s.distinct_lists);
  out.i64(s.memory_bytes);
  out.f64(s.build_seconds);

  if (bytes.size() != kHeaderSize + payload_size) throw std::logic_error("serializeCflModel: size bookkeeping is off");
  detail::resealCflBuffer(bytes.data(), bytes.size());
  return std::move(bytes);
}

namespace {

// Checks the header from its first `available` bytes (at most kHeaderSize are read) of a file of
// `total_size` bytes and returns the payload size. Lets loadCflModel refuse another kind of file, or a file
// whose size does not match its header, before reading it all.
std::uint64_t checkHeader(const unsigned char* data, std::size_t available, std::uint64_t total_size,
                          const std::string& name) {
  const auto fail = [&](const std::string& message) { throw Error(name + ": " + message); };
  // In the order that gives the most useful message: another kind of file first, then a file from a foreign
  // writer or a later version (whose header may differ past this point), then corruption.
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
    if (marker == 0x04030201u) fail("written in big-endian byte order (marker bytes 01 02 03 04); files are little-endian");
    fail("bad endianness marker (bytes " + hexBytes(data + 8, 4) + ", expected 04 03 02 01)");
  }
  const std::uint32_t version = loadU32(data + 12);
  if (version != 1 && version != kCflFileVersion) {
    fail("format version " + std::to_string(version) + " is not supported (this library reads versions 1 to " +
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
  TriangleMesh mesh;
  bool seen_mesh = false, seen_grid = false, seen_list = false, seen_bounds = false, seen_statistics = false,
       seen_entry_bounds = false;
  const std::uint32_t version = loadU32(data + 12);
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
    } else if (tag == kTagGrid) {
      once(seen_grid);
      for (int axis = 0; axis < 3; ++axis) model.grid.origin[axis] = in.f64("grid origin");
      model.grid.voxel_size = in.f64("voxel size");
      for (int axis = 0; axis < 3; ++axis) model.grid.dims[axis] = in.i32("grid dims");
      model.padding = in.f64("padding");
      const std::uint32_t flags = in.u32("flags");
      if (flags > 1u) in.fail("unknown flags " + hexU32(flags));
      model.topology_culling = (flags & 1u) != 0;
    } else if (tag == kTagList) {
      once(seen_list);
      const std::size_t voxel_count = in.count(4, "voxel_list size");
      const std::size_t offset_count = in.count(4, "list_offsets size");
      const std::size_t id_count = in.count(4, "list_triangles size");
      if (in.remaining() / 4 < voxel_count || in.remaining() / 4 - voxel_count < offset_count ||
          in.remaining() / 4 - voxel_count - offset_count < id_count) {
        in.fail("array sizes " + std::to_string(voxel_count) + " + " + std::to_string(offset_count) + " + " +
                std::to_string(id_count) + " do not fit in the section");
      }
      model.voxel_list.resize(voxel_count);
      in.array(model.voxel_list, "voxel_list");
      model.list_offsets.resize(offset_count);
      in.array(model.list_offsets, "list_offsets");
      model.list_triangles.resize(id_count);
      in.array(model.list_triangles, "list_triangles");
    } else if (tag == kTagEntryBounds && version >= 2) {
      once(seen_entry_bounds);
      const std::size_t entry_count = in.count(1, "list_entry_bounds size");
      if (in.remaining() < entry_count) {
        in.fail("array size " + std::to_string(entry_count) + " does not fit in the section");
      }
      model.list_entry_bounds.resize(entry_count);
      in.array(model.list_entry_bounds, "list_entry_bounds");
    } else if (tag == kTagBounds) {
      once(seen_bounds);
      const std::size_t voxel_count = in.count(8, "voxel_lower_bound size");
      const std::size_t corner_count = in.count(8, "corner_distance size");
      if (in.remaining() / 8 < voxel_count || in.remaining() / 8 - voxel_count < corner_count) {
        in.fail("array sizes " + std::to_string(voxel_count) + " + " + std::to_string(corner_count) +
                " do not fit in the section");
      }
      model.voxel_lower_bound.resize(voxel_count);
      in.array(model.voxel_lower_bound, "voxel_lower_bound");
      model.corner_distance.resize(corner_count);
      in.array(model.corner_distance, "corner_distance");
    } else if (tag == kTagStatistics) {
      once(seen_statistics);
      BuildStatistics& s = model.statistics;
      const std::int64_t resolution = in.i64("resolution");
      if (resolution < 0 || resolution > std::numeric_limits<int>::max()) in.fail("resolution out of range");
      s.resolution = static_cast<int>(resolution);
      s.voxel_count = in.i64("voxel count");
      s.average_list_length = in.f64("average list length");
      s.longest_list = in.i64("longest list");
      s.distinct_lists = in.i64("distinct lists");
      s.memory_bytes = in.i64("memory bytes");
      s.build_seconds = in.f64("build seconds");
    } else {
      continue;  // A section added by a later writer of the same version: not needed to answer queries.
    }
    if (in.remaining() != 0) in.fail(std::to_string(in.remaining()) + " unexpected bytes at the end of the section");
  }
  const char* missing = !seen_mesh ? "MESH" : !seen_grid ? "GRID" : !seen_list ? "LIST" : !seen_bounds ? "BNDS"
                        : !seen_statistics ? "STAT" : nullptr;
  if (missing) fail(std::string("required section ") + missing + " is missing");
  if (version >= 2 && !seen_entry_bounds) fail("required section LBND is missing");
  // Version 1 lists are sorted by id and carry no bounds: bound 0 for every entry is true and keeps them sorted.
  if (version == 1) model.list_entry_bounds.assign(model.list_triangles.size(), 0);

  try {
    model.geometry = makeMeshModel(std::move(mesh));
  } catch (const Error& error) {
    fail(std::string("MESH section: ") + error.what());
  }
  validateModelStructure(model, name);
  return model;
}

void saveCflModel(const CflModel& model, const std::string& path) {
  const std::vector<unsigned char> bytes = serializeCflModel(model);
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
    file.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    file.close();
    if (!file) {
      const std::string reason = std::strerror(errno);
      std::remove(temporary_path.c_str());
      throw Error(path + ": writing " + std::to_string(bytes.size()) + " bytes failed: " + reason);
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
