// CFL model files: a loaded model is the saved one (every query answers bit-identically), the bytes follow
// the documented little-endian layout, and every kind of damaged, hostile or foreign file is refused with a
// cfl::Error naming the file and the defect - never a crash, a hang, a huge allocation or a model that
// answers differently.

#include "cfl/cfl_file.h"
#include "cfl/cfl_model.h"
#include "cfl/cfl_query.h"
#include "cfl/error.h"
#include "support/test_meshes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <sstream>
#include <streambuf>
#include <string>
#include <vector>

namespace cfl {
namespace {

using Bytes = std::vector<unsigned char>;
constexpr const char* kName = "model_under_test.cfl";

bool sameBits(double x, double y) { return std::memcmp(&x, &y, sizeof(double)) == 0; }
bool sameBits(const Eigen::Vector3d& x, const Eigen::Vector3d& y) { return std::memcmp(x.data(), y.data(), 24) == 0; }
template <typename T>
bool sameBits(const std::vector<T>& x, const std::vector<T>& y) {
  return x.size() == y.size() && (x.empty() || std::memcmp(x.data(), y.data(), sizeof(T) * x.size()) == 0);
}

// Bitwise equality of two query answers, counters included (same work means the same search).
void expectSameAnswer(const DistanceResult& expected, const DistanceResult& actual, const std::string& where) {
  EXPECT_TRUE(sameBits(expected.distance, actual.distance)) << where << ": " << expected.distance << " vs " << actual.distance;
  EXPECT_TRUE(sameBits(expected.point_a, actual.point_a)) << where;
  EXPECT_TRUE(sameBits(expected.point_b, actual.point_b)) << where;
  EXPECT_EQ(expected.triangle_a, actual.triangle_a) << where;
  EXPECT_EQ(expected.triangle_b, actual.triangle_b) << where;
  EXPECT_EQ(expected.counters.triangle_pairs, actual.counters.triangle_pairs) << where;
  EXPECT_EQ(expected.counters.voxel_tests, actual.counters.voxel_tests) << where;
}

// Field-by-field equality of two models, the derived Bvh included; floats and doubles bit for bit.
void expectSameModel(const CflModel& a, const CflModel& b) {
  ASSERT_EQ(a.geometry.mesh.vertices.size(), b.geometry.mesh.vertices.size());
  for (std::size_t v = 0; v < a.geometry.mesh.vertices.size(); ++v) {
    ASSERT_TRUE(sameBits(a.geometry.mesh.vertices[v], b.geometry.mesh.vertices[v])) << "vertex " << v;
  }
  EXPECT_EQ(a.geometry.mesh.triangles, b.geometry.mesh.triangles);
  ASSERT_EQ(a.geometry.bvh.nodes.size(), b.geometry.bvh.nodes.size());
  for (std::size_t n = 0; n < a.geometry.bvh.nodes.size(); ++n) {
    const BvhNode &x = a.geometry.bvh.nodes[n], &y = b.geometry.bvh.nodes[n];
    ASSERT_TRUE(sameBits(x.box().min, y.box().min) && sameBits(x.box().max, y.box().max) && sameBits(x.center, y.center) &&
                sameBits(x.radius, y.radius) && x.first == y.first && x.count == y.count)
        << "bvh node " << n;
  }
  EXPECT_EQ(a.geometry.bvh.triangle_ids, b.geometry.bvh.triangle_ids);
  const RegionTree &r = a.regions, &s = b.regions;
  EXPECT_TRUE(sameBits(r.origin, s.origin));
  EXPECT_TRUE(sameBits(r.root_size, s.root_size));
  EXPECT_EQ(r.root_dims, s.root_dims);
  EXPECT_EQ(r.max_depth, s.max_depth);
  EXPECT_TRUE(sameBits(a.padding, b.padding));
  EXPECT_EQ(a.topology_culling, b.topology_culling);
  EXPECT_EQ(r.nodes, s.nodes);
  EXPECT_EQ(r.leaf_list, s.leaf_list);
  EXPECT_TRUE(sameBits(r.leaf_lower_bound, s.leaf_lower_bound));
  EXPECT_TRUE(sameBits(r.leaf_corner_distance, s.leaf_corner_distance));
  EXPECT_TRUE(sameBits(r.corner_distance_unit, s.corner_distance_unit));
  EXPECT_EQ(r.list_offsets, s.list_offsets);
  EXPECT_EQ(r.list_entry_ids, s.list_entry_ids);
  EXPECT_EQ(r.list_high_ids, s.list_high_ids);
  EXPECT_EQ(r.listTriangles(), s.listTriangles());
  EXPECT_EQ(r.list_entry_bounds, s.list_entry_bounds);
  EXPECT_EQ(a.statistics.resolution, b.statistics.resolution);
  EXPECT_EQ(a.statistics.voxel_count, b.statistics.voxel_count);
  EXPECT_EQ(a.statistics.leaves_per_depth, b.statistics.leaves_per_depth);
  EXPECT_EQ(a.statistics.distinct_lists, b.statistics.distinct_lists);
  EXPECT_EQ(a.statistics.longest_list, b.statistics.longest_list);
  EXPECT_EQ(a.statistics.memory_bytes, b.statistics.memory_bytes);
  EXPECT_EQ(a.statistics.coarsened, b.statistics.coarsened);
  EXPECT_TRUE(sameBits(a.statistics.average_list_length, b.statistics.average_list_length));
  EXPECT_TRUE(sameBits(a.statistics.build_seconds, b.statistics.build_seconds));
}

// Queries `loaded` and `original` with the same B at random poses, from far to overlapping, in both modes
// and both overloads, and expects bit-identical answers.
void expectSameAnswers(const CflModel& original, const CflModel& loaded, const CflModel& b, int poses,
                       std::uint64_t seed) {
  test::Rng rng(seed);
  const double range = original.geometry.bounds.diagonal();
  for (int i = 0; i < poses; ++i) {
    const Eigen::Isometry3d X_WA = test::randomPose(rng, 0.2 * range);
    // Translations from inside A to well outside its padded regions.
    const Eigen::Isometry3d X_WB = test::randomPose(rng, (i % 3 + 0.25) * range);
    for (QueryMode mode : {QueryMode::kHierarchical, QueryMode::kPaper}) {
      DistanceOptions options;
      options.mode = mode;
      const std::string where = "pose " + std::to_string(i) + (mode == QueryMode::kPaper ? " paper" : " hierarchical");
      expectSameAnswer(computeDistance(original, X_WA, b.geometry, X_WB, options),
                       computeDistance(loaded, X_WA, b.geometry, X_WB, options), where + " mesh B");
      expectSameAnswer(computeDistance(original, X_WA, b, X_WB, options),
                       computeDistance(loaded, X_WA, b, X_WB, options), where + " cfl B");
      expectSameAnswer(computeDistance(b, X_WB, original, X_WA, options),
                       computeDistance(b, X_WB, loaded, X_WA, options), where + " as B");
    }
  }
}

// resolution 0: adaptive regions; N > 0: a uniform grid of N cells along the longest axis.
CflModel build(const TriangleMesh& mesh, int resolution, double padding = 2.0, bool topology_culling = false) {
  BuildOptions options;
  options.resolution = resolution;
  options.padding = padding;
  options.topology_culling = topology_culling;
  return buildCflModel(mesh, options);
}

TriangleMesh squashed(TriangleMesh mesh, double factor) {
  for (Eigen::Vector3d& p : mesh.vertices) p.tail<2>() *= factor;
  return mesh;
}

// A small uniform model (12 triangles, a few dozen cells), so that every byte offset can be tried.
const CflModel& smallModel() {
  static const CflModel model = build(test::makeBox(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 2, 3)), 4);
  return model;
}

// The depth of every node (parents come before their children).
std::vector<int> nodeDepths(const RegionTree& tree) {
  std::vector<int> depth(tree.nodes.size(), 0);
  for (std::size_t n = 0; n < tree.nodes.size(); ++n) {
    if (!(tree.nodes[n] & RegionTree::kLeafBit)) {
      for (int c = 0; c < 8; ++c) depth[tree.nodes[n] + c] = depth[n] + 1;
    }
  }
  return depth;
}

// Splits leaf node `node` of `model` into eight children appended to the nodes: child 0 keeps the old
// leaf, the other seven are new leaves with its list and lower bound and corner distances 0. The model
// stays exact: a list and a lower bound that hold for a cell hold for its parts (entry bounds count in
// finer units there, so they only get lower), and 0 is a true lower bound at any corner. Returns the
// index of child 0.
std::size_t split(CflModel& model, std::size_t node) {
  RegionTree& tree = model.regions;
  const std::uint32_t old_leaf = tree.nodes[node] & ~RegionTree::kLeafBit;
  const std::uint32_t block = static_cast<std::uint32_t>(tree.nodes.size());
  tree.nodes[node] = block;
  tree.nodes.push_back(RegionTree::kLeafBit | old_leaf);
  for (int c = 1; c < 8; ++c) {
    tree.nodes.push_back(RegionTree::kLeafBit | static_cast<std::uint32_t>(tree.leaf_list.size()));
    tree.leaf_list.push_back(tree.leaf_list[old_leaf]);
    tree.leaf_lower_bound.push_back(tree.leaf_lower_bound[old_leaf]);
    tree.leaf_corner_distance.push_back({});
  }
  // The figures the loader checks against the tree.
  const std::vector<int> depths = nodeDepths(tree);
  tree.max_depth = std::max(tree.max_depth, depths[block]);
  BuildStatistics& s = model.statistics;
  s.voxel_count = tree.leafCount();
  s.leaves_per_depth.assign(tree.max_depth + 1, 0);
  for (std::size_t n = 0; n < tree.nodes.size(); ++n) {
    if (tree.nodes[n] & RegionTree::kLeafBit) ++s.leaves_per_depth[depths[n]];
  }
  return block;
}

// Replaces leaf node `node` by a chain of cells `depth` levels deep: at every level child 0 is split again.
CflModel deepened(const CflModel& good, std::size_t node, int depth) {
  CflModel model = good;
  for (int level = 0; level < depth; ++level) node = split(model, node);
  return model;
}

// A small adaptive model: a soup squashed into a rod, so that the root grid is one row of cells. The
// structure tests need two split root cells and a cell two levels down; where the builder's refinement
// rules (free to change) did not make them, they are made here by splitting leaves, which keeps the
// model exact.
const CflModel& adaptiveModel() {
  static const CflModel model = [] {
    CflModel built = build(squashed(test::makeTriangleSoup(30, 2, 1.0, 0.2), 0.05), 0, 1.0);
    const auto splitRoots = [&] {
      std::vector<std::size_t> roots;
      for (std::int64_t r = 0; r < built.regions.rootCount(); ++r) {
        if (!(built.regions.nodes[r] & RegionTree::kLeafBit)) roots.push_back(std::size_t(r));
      }
      return roots;
    };
    for (std::int64_t r = 1; splitRoots().size() < 2 && r < built.regions.rootCount(); r += 2) {
      if (built.regions.nodes[r] & RegionTree::kLeafBit) split(built, std::size_t(r));
    }
    if (built.regions.max_depth < 2) {
      // A leaf below the first split root is split in turn.
      std::size_t node = built.regions.nodes[splitRoots()[0]];
      while (!(built.regions.nodes[node] & RegionTree::kLeafBit)) node = built.regions.nodes[node];
      split(built, node);
    }
    return built;
  }();
  return model;
}

// The nodes that are leaves (`leaves` true) or that have children (false), in index order.
std::vector<std::size_t> nodesWhere(const RegionTree& tree, bool leaves) {
  std::vector<std::size_t> found;
  for (std::size_t n = 0; n < tree.nodes.size(); ++n) {
    if (bool(tree.nodes[n] & RegionTree::kLeafBit) == leaves) found.push_back(n);
  }
  return found;
}

// Appends little-endian values, as docs/cfl_file_format.md lays them out.
struct ByteWriter {
  Bytes bytes;
  void u32(std::uint32_t value) {
    for (int i = 0; i < 4; ++i) bytes.push_back(static_cast<unsigned char>(value >> (8 * i)));
  }
  void u64(std::uint64_t value) {
    for (int i = 0; i < 8; ++i) bytes.push_back(static_cast<unsigned char>(value >> (8 * i)));
  }
  void f64(double value) {
    std::uint64_t bits;
    std::memcpy(&bits, &value, 8);
    u64(bits);
  }
  void u16(std::uint16_t value) {
    for (int i = 0; i < 2; ++i) bytes.push_back(static_cast<unsigned char>(value >> (8 * i)));
  }
  void f32(float value) {
    std::uint32_t bits;
    std::memcpy(&bits, &value, 4);
    u32(bits);
  }
  void tag(const char* name) { bytes.insert(bytes.end(), name, name + 4); }
};

// An independent writer of the documented byte map that checks nothing, so that tests can write any model,
// broken ones included. The layout test expects it to agree with serializeCflModel byte for byte.
Bytes writeUnchecked(const CflModel& model) {
  const TriangleMesh& mesh = model.geometry.mesh;
  const RegionTree& tree = model.regions;
  const BuildStatistics& s = model.statistics;
  ByteWriter payload;
  const auto section = [&](const char* tag, const std::function<void(ByteWriter&)>& body) {
    ByteWriter out;
    body(out);
    payload.tag(tag);
    payload.u32(0);
    payload.u64(out.bytes.size());
    payload.bytes.insert(payload.bytes.end(), out.bytes.begin(), out.bytes.end());
  };
  section("MESH", [&](ByteWriter& out) {
    out.u64(mesh.vertices.size());
    out.u64(mesh.triangles.size());
    for (const Eigen::Vector3d& p : mesh.vertices) out.f64(p.x()), out.f64(p.y()), out.f64(p.z());
    for (const auto& t : mesh.triangles) out.u32(t[0]), out.u32(t[1]), out.u32(t[2]);
  });
  section("TREE", [&](ByteWriter& out) {
    for (int axis = 0; axis < 3; ++axis) out.f64(tree.origin[axis]);
    out.f64(tree.root_size);
    for (int axis = 0; axis < 3; ++axis) out.u32(static_cast<std::uint32_t>(tree.root_dims[axis]));
    out.u32(static_cast<std::uint32_t>(tree.max_depth));
    out.f64(model.padding);
    out.u32(model.topology_culling ? 1 : 0);
    out.f64(tree.corner_distance_unit);
  });
  section("NODE", [&](ByteWriter& out) {
    out.u64(tree.nodes.size());
    for (std::uint32_t value : tree.nodes) out.u32(value);
  });
  section("LEAF", [&](ByteWriter& out) {
    out.u64(tree.leaf_list.size());
    for (std::uint32_t list : tree.leaf_list) out.u32(list);
    for (float bound : tree.leaf_lower_bound) out.f32(bound);
    for (const auto& corners : tree.leaf_corner_distance) {
      for (std::uint16_t distance : corners) out.u16(distance);
    }
  });
  section("LIST", [&](ByteWriter& out) {
    out.u64(tree.list_offsets.size());
    const std::vector<std::int32_t> ids = tree.listTriangles();
    out.u64(ids.size());
    for (std::uint32_t offset : tree.list_offsets) out.u32(offset);
    for (std::int32_t id : ids) out.u32(static_cast<std::uint32_t>(id));
  });
  section("LBND", [&](ByteWriter& out) {
    out.u64(tree.list_entry_bounds.size());
    out.bytes.insert(out.bytes.end(), tree.list_entry_bounds.begin(), tree.list_entry_bounds.end());
  });
  section("STAT", [&](ByteWriter& out) {
    out.u64(static_cast<std::uint64_t>(s.resolution));
    out.u64(static_cast<std::uint64_t>(s.voxel_count));
    out.u64(static_cast<std::uint64_t>(s.leaves_without_list));
    out.f64(s.average_list_length);
    out.u64(static_cast<std::uint64_t>(s.longest_list));
    out.u64(static_cast<std::uint64_t>(s.distinct_lists));
    out.u64(static_cast<std::uint64_t>(s.memory_bytes));
    out.f64(s.build_seconds);
    out.u32(s.coarsened ? 1 : 0);
    out.u64(s.leaves_per_depth.size());
    for (std::int64_t count : s.leaves_per_depth) out.u64(static_cast<std::uint64_t>(count));
  });
  ByteWriter file;
  const unsigned char magic[8] = {0x89, 'C', 'F', 'L', '\r', '\n', 0x1A, '\n'};
  file.bytes.assign(magic, magic + 8);
  file.u32(0x01020304u);
  file.u32(kCflFileVersion);
  file.u64(payload.bytes.size());
  file.u64(0);  // the checksums, sealed below
  file.bytes.insert(file.bytes.end(), payload.bytes.begin(), payload.bytes.end());
  detail::resealCflBuffer(file.bytes.data(), file.bytes.size());
  return file.bytes;
}

// The byte offset of the body of the section tagged `tag` (after its 16-byte section header), found by
// walking the documented layout.
std::size_t sectionBody(const Bytes& bytes, const char* tag) {
  std::size_t position = 32;
  while (position + 16 <= bytes.size()) {
    std::uint64_t length = 0;
    for (int i = 0; i < 8; ++i) length |= std::uint64_t(bytes[position + 8 + i]) << (8 * i);
    if (std::memcmp(&bytes[position], tag, 4) == 0) return position + 16;
    position += 16 + length;
  }
  ADD_FAILURE() << "no section " << tag;
  return 0;
}

void putU32(Bytes& bytes, std::size_t at, std::uint32_t value) {
  for (int i = 0; i < 4; ++i) bytes[at + i] = static_cast<unsigned char>(value >> (8 * i));
}
void putU64(Bytes& bytes, std::size_t at, std::uint64_t value) {
  for (int i = 0; i < 8; ++i) bytes[at + i] = static_cast<unsigned char>(value >> (8 * i));
}
void putF64(Bytes& bytes, std::size_t at, double value) {
  std::uint64_t bits;
  std::memcpy(&bits, &value, 8);
  putU64(bytes, at, bits);
}
void putF32(Bytes& bytes, std::size_t at, float value) {
  std::uint32_t bits;
  std::memcpy(&bits, &value, 4);
  putU32(bytes, at, bits);
}
std::uint32_t getU32(const Bytes& bytes, std::size_t at) {
  std::uint32_t value = 0;
  for (int i = 0; i < 4; ++i) value |= std::uint32_t(bytes[at + i]) << (8 * i);
  return value;
}
std::uint64_t getU64(const Bytes& bytes, std::size_t at) {
  return std::uint64_t(getU32(bytes, at)) | std::uint64_t(getU32(bytes, at + 4)) << 32;
}

// Bit-by-bit CRC-32, written from the definition: an independent reference for the library's (zlib's).
std::uint32_t referenceCrc32(const unsigned char* data, std::size_t size) {
  std::uint32_t crc = 0xFFFFFFFFu;
  for (std::size_t i = 0; i < size; ++i) {
    crc ^= data[i];
    for (int bit = 0; bit < 8; ++bit) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
  }
  return ~crc;
}

// Expects deserializing `bytes` to throw a cfl::Error whose message names the file and contains `expected`.
void expectRefused(const Bytes& bytes, const std::string& expected) {
  try {
    deserializeCflModel(bytes.data(), bytes.size(), kName);
    ADD_FAILURE() << "loaded a file that should be refused (" << expected << ")";
  } catch (const Error& error) {
    const std::string message = error.what();
    EXPECT_EQ(message.rfind(kName, 0), 0u) << message;
    EXPECT_NE(message.find(expected), std::string::npos) << "expected '" << expected << "' in: " << message;
  }
}

// Expects both writers, to memory and to a stream, to refuse `model` with `expected` in the message, and the
// stream writer to write nothing.
void expectWritersRefuse(const CflModel& model, const std::string& expected) {
  for (bool to_stream : {false, true}) {
    SCOPED_TRACE(to_stream ? "writeCflModel" : "serializeCflModel");
    std::ostringstream stream;
    try {
      if (to_stream) {
        writeCflModel(model, stream);
      } else {
        serializeCflModel(model);
      }
      ADD_FAILURE() << "saved a model that should be refused (" << expected << ")";
    } catch (const Error& error) {
      const std::string message = error.what();
      EXPECT_EQ(message.rfind("cannot save CFL model: ", 0), 0u) << message;
      EXPECT_NE(message.find(expected), std::string::npos) << "expected '" << expected << "' in: " << message;
    }
    EXPECT_TRUE(stream.str().empty());
  }
}

// Expects `model` to be refused by the loader (written with writeUnchecked) and by the writers, all with
// `expected` in the message.
void expectModelRefused(const CflModel& model, const std::string& expected) {
  expectRefused(writeUnchecked(model), expected);
  expectWritersRefuse(model, expected);
}

// Expects the writers to refuse `model` with `expected` in the message, for defects that the file cannot
// even express (it stores one leaf count for the three leaf arrays).
void expectSaveRefused(const CflModel& model, const std::string& expected) { expectWritersRefuse(model, expected); }

std::string temporaryPath(const std::string& stem) {
  return (std::filesystem::temp_directory_path() /
          (stem + "_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + ".cfl"))
      .string();
}

TEST(CflFile, LoadedModelAnswersEveryQueryBitIdentically) {
  const CflModel b = build(test::makeTorus(0.5, 0.15, 16, 8), 0);
  struct Case {
    const char* name;
    CflModel model;
  };
  const Case cases[] = {
      {"torus knot, adaptive", build(test::makeTorusKnot(2, 3, 0.5), 0)},
      {"torus knot, uniform", build(test::makeTorusKnot(2, 3, 0.5), 16)},
      {"messy, adaptive", build(test::makeMessyMesh(), 0, 1.5)},
      {"messy, uniform", build(test::makeMessyMesh(), 12, 1.5)},
      {"open hemisphere, topology culling, adaptive", build(test::makeHemisphere(), 0, 2.0, true)},
      {"open hemisphere, topology culling, uniform", build(test::makeHemisphere(), 10, 2.0, true)},
      {"triangle soup, adaptive", build(test::makeTriangleSoup(200, 7), 0, 1.0)},
      {"bunny, uniform", build(test::loadBunny(), 20)},
      {"small adaptive rod", adaptiveModel()},
  };
  bool some_refined = false;
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    some_refined |= c.model.regions.max_depth > 0;
    const Bytes bytes = serializeCflModel(c.model);
    const CflModel loaded = deserializeCflModel(bytes.data(), bytes.size(), c.name);
    expectSameModel(c.model, loaded);
    expectSameAnswers(c.model, loaded, b, 12, 42);
    // The format has one encoding per model: saving the loaded model gives the same bytes.
    EXPECT_EQ(bytes, serializeCflModel(loaded));
  }
  EXPECT_TRUE(some_refined) << "no adaptive model was refined: the tree part of the format went untested";
}

// An output stream buffer like a pipe's: it keeps what it is given, fails every seek (and counts the
// attempts), and fails for good once `capacity` bytes are written.
class PipeBuffer : public std::streambuf {
 public:
  explicit PipeBuffer(std::size_t capacity = std::numeric_limits<std::size_t>::max()) : capacity_(capacity) {}
  Bytes bytes;
  int seeks = 0;
  int writes = 0;

 protected:
  std::streamsize xsputn(const char* data, std::streamsize count) override {
    ++writes;
    const std::size_t taken = std::min(static_cast<std::size_t>(count), capacity_ - bytes.size());
    bytes.insert(bytes.end(), data, data + taken);
    return static_cast<std::streamsize>(taken);
  }
  int_type overflow(int_type c) override {
    if (traits_type::eq_int_type(c, traits_type::eof())) return traits_type::not_eof(c);
    const char byte = traits_type::to_char_type(c);
    return xsputn(&byte, 1) == 1 ? c : traits_type::eof();
  }
  pos_type seekoff(off_type, std::ios_base::seekdir, std::ios_base::openmode) override {
    ++seeks;
    return pos_type(off_type(-1));
  }
  pos_type seekpos(pos_type, std::ios_base::openmode) override {
    ++seeks;
    return pos_type(off_type(-1));
  }

 private:
  std::size_t capacity_;
};

TEST(CflFile, StreamWriterWritesTheSerializedBytesInPiecesWithoutSeeking) {
  const CflModel bunny = build(test::loadBunny(), 20);
  for (const CflModel* model : {&smallModel(), &adaptiveModel(), &bunny}) {
    const Bytes expected = serializeCflModel(*model);
    PipeBuffer pipe;
    std::ostream stream(&pipe);
    writeCflModel(*model, stream);
    EXPECT_TRUE(stream.good());
    EXPECT_EQ(pipe.seeks, 0);
    EXPECT_EQ(pipe.bytes, expected);
    if (model == &bunny) {
      // Held whole, the file would be one write; streamed, no piece is much larger than the largest array.
      ASSERT_GT(expected.size(), std::size_t(1) << 20);
      EXPECT_GT(pipe.writes, 4);
    }
  }
}

TEST(CflFile, StreamWriteFailureIsReportedAndLeavesAFileTheLoaderRefuses) {
  const CflModel& model = adaptiveModel();
  const Bytes expected = serializeCflModel(model);
  for (std::size_t capacity : {std::size_t(0), std::size_t(31), std::size_t(100), expected.size() / 2,
                               expected.size() - 1}) {
    SCOPED_TRACE("capacity " + std::to_string(capacity));
    PipeBuffer pipe(capacity);
    std::ostream stream(&pipe);
    try {
      writeCflModel(model, stream);
      ADD_FAILURE() << "no error from a stream that failed";
    } catch (const Error& error) {
      EXPECT_NE(std::string(error.what()).find("the stream failed after"), std::string::npos) << error.what();
      EXPECT_NE(std::string(error.what()).find("of " + std::to_string(expected.size()) + " bytes"), std::string::npos)
          << error.what();
    }
    ASSERT_EQ(pipe.bytes.size(), capacity);
    EXPECT_TRUE(std::equal(pipe.bytes.begin(), pipe.bytes.end(), expected.begin()));
    EXPECT_THROW(deserializeCflModel(pipe.bytes.data(), pipe.bytes.size(), kName), Error);
  }
}

// saveCflModel writes its payload once and rewrites the header with the checksum; the file must hold the
// very bytes serializeCflModel (two passes, no seeking) makes, header checksums included.
TEST(CflFile, SavedFileHoldsTheSerializedBytes) {
  const CflModel bunny = build(test::loadBunny(), 0);
  const std::string path = temporaryPath("cfl_file_test_saved_bytes");
  for (const CflModel* model : {&smallModel(), &adaptiveModel(), &bunny}) {
    saveCflModel(*model, path);
    std::ifstream file(path, std::ios::binary);
    const Bytes saved((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
    EXPECT_EQ(saved, serializeCflModel(*model));
  }
  std::filesystem::remove(path);
}

TEST(CflFile, SaveThenLoadThroughTheFileSystemGivesTheSameModel) {
  const CflModel model = build(test::makeTorusKnot(3, 2, 0.4), 0);
  const std::string path = temporaryPath("cfl_file_test_roundtrip");
  saveCflModel(model, path);
  const CflModel loaded = loadCflModel(path);
  expectSameModel(model, loaded);
  const CflModel b = build(test::makeWavySheet(), 8);
  expectSameAnswers(model, loaded, b, 6, 7);
  // Saving over an existing file replaces it and leaves no temporary behind.
  saveCflModel(smallModel(), path);
  expectSameModel(smallModel(), loadCflModel(path));
  for (const auto& entry : std::filesystem::directory_iterator(std::filesystem::path(path).parent_path())) {
    EXPECT_EQ(entry.path().string().find(path + ".tmp"), std::string::npos) << entry.path();
  }
  std::filesystem::remove(path);
}

TEST(CflFile, BytesFollowTheDocumentedLittleEndianLayout) {
  for (const CflModel* model : {&smallModel(), &adaptiveModel()}) {
    const Bytes bytes = serializeCflModel(*model);
    ASSERT_GE(bytes.size(), 32u);
    const unsigned char magic[8] = {0x89, 'C', 'F', 'L', '\r', '\n', 0x1A, '\n'};
    EXPECT_EQ(0, std::memcmp(bytes.data(), magic, 8));
    EXPECT_EQ(bytes[8], 0x04);
    EXPECT_EQ(bytes[9], 0x03);
    EXPECT_EQ(bytes[10], 0x02);
    EXPECT_EQ(bytes[11], 0x01);
    EXPECT_EQ(getU32(bytes, 12), 4u);
    EXPECT_EQ(kCflFileVersion, 4u);
    EXPECT_EQ(getU64(bytes, 16), bytes.size() - 32);
    EXPECT_EQ(getU32(bytes, 24), referenceCrc32(bytes.data() + 32, bytes.size() - 32));
    EXPECT_EQ(getU32(bytes, 28), referenceCrc32(bytes.data(), 28));
    // Every byte where the byte map in docs/cfl_file_format.md puts it, sections in the documented order.
    EXPECT_EQ(bytes, writeUnchecked(*model));
    const char* order[] = {"MESH", "TREE", "NODE", "LEAF", "LIST", "LBND", "STAT"};
    for (int i = 0; i + 1 < 7; ++i) EXPECT_LT(sectionBody(bytes, order[i]), sectionBody(bytes, order[i + 1])) << order[i];
    EXPECT_EQ(getU64(bytes, sectionBody(bytes, "TREE") - 8), 68u);
    EXPECT_EQ(getU64(bytes, sectionBody(bytes, "LEAF") - 8), 8 + 24 * model->regions.leaf_list.size());
  }
}

TEST(CflFile, Crc32MatchesTheStandardCheckValueAndABitwiseReference) {
  const char* check = "123456789";
  EXPECT_EQ(detail::crc32(reinterpret_cast<const unsigned char*>(check), 9), 0xCBF43926u);
  test::Rng rng(3);
  Bytes data(1000);
  for (auto& byte : data) byte = static_cast<unsigned char>(rng());
  for (std::size_t size : {0, 1, 7, 8, 9, 15, 16, 17, 999, 1000}) {
    EXPECT_EQ(detail::crc32(data.data(), size), referenceCrc32(data.data(), size)) << size;
  }
}

TEST(CflFile, FilesOfAnotherKindAreRefusedAsSuch) {
  expectRefused({}, "not a CFL model file");
  const std::string obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  expectRefused(Bytes(obj.begin(), obj.end()), "not a CFL model file");
  const Bytes elf = {0x7f, 'E', 'L', 'F', 2, 1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0};
  expectRefused(elf, "not a CFL model file");
  // The magic alone, then a file cut inside the header.
  Bytes bytes = serializeCflModel(smallModel());
  expectRefused(Bytes(bytes.begin(), bytes.begin() + 8), "truncated");
  expectRefused(Bytes(bytes.begin(), bytes.begin() + 31), "truncated");
}

TEST(CflFile, WrongVersionAndEndiannessAreNamed) {
  const Bytes good = serializeCflModel(smallModel());
  Bytes bytes = good;
  putU32(bytes, 12, kCflFileVersion + 1);
  detail::resealCflBuffer(bytes.data(), bytes.size());
  expectRefused(bytes, "format version " + std::to_string(kCflFileVersion + 1) + " is not supported");

  bytes = good;
  bytes[8] = 1, bytes[9] = 2, bytes[10] = 3, bytes[11] = 4;
  expectRefused(bytes, "big-endian");
  bytes[8] = 0xFF;
  expectRefused(bytes, "endianness marker");
}

// Versions 1 and 2 held a uniform grid, version 3 float corner distances; no loader is kept for them, and
// the message says what to do.
TEST(CflFile, VersionsOneToThreeAreRefusedWithTheRebuildMessage) {
  for (std::uint32_t version : {1u, 2u, 3u}) {
    Bytes bytes = serializeCflModel(smallModel());
    putU32(bytes, 12, version);
    const std::string expected = std::string(kName) + ": a version-" + std::to_string(version) +
                                 (version == 3 ? " CFL file (float corner distances)" : " CFL file (uniform grid)") +
                                 " from an earlier cfl: rebuild it with `cfl build`";
    // As an old file is (its checksums right for it), and as edited here (its header checksum now wrong):
    // the version is named first either way.
    for (bool reseal : {true, false}) {
      Bytes file = bytes;
      if (reseal) detail::resealCflBuffer(file.data(), file.size());
      try {
        deserializeCflModel(file.data(), file.size(), kName);
        ADD_FAILURE() << "loaded a version-" << version << " file";
      } catch (const Error& error) {
        EXPECT_EQ(std::string(error.what()), expected);
      }
    }
  }
  // Through the file system, the header alone decides.
  Bytes bytes = serializeCflModel(smallModel());
  putU32(bytes, 12, 2);
  detail::resealCflBuffer(bytes.data(), bytes.size());
  const std::string path = temporaryPath("cfl_file_test_version_2");
  std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  try {
    loadCflModel(path);
    ADD_FAILURE() << "loaded a version-2 file";
  } catch (const Error& error) {
    EXPECT_EQ(std::string(error.what()),
              path + ": a version-2 CFL file (uniform grid) from an earlier cfl: rebuild it with `cfl build`");
  }
  std::filesystem::remove(path);
}

TEST(CflFile, CorruptionIsCaughtByTheChecksums) {
  const Bytes good = serializeCflModel(smallModel());
  Bytes bytes = good;
  bytes[good.size() / 2] ^= 0x10;
  expectRefused(bytes, "checksum mismatch");
  bytes = good;
  bytes[20] ^= 0x01;  // payload size, in the header
  expectRefused(bytes, "header checksum mismatch");
  bytes = good;
  bytes[24] ^= 0x80;  // the payload checksum itself
  expectRefused(bytes, "checksum mismatch");
}

TEST(CflFile, TruncationAtEveryByteOffsetIsRefused) {
  for (const CflModel* model : {&smallModel(), &adaptiveModel()}) {
    const Bytes good = serializeCflModel(*model);
    ASSERT_LT(good.size(), 100000u) << "the small models grew; this test tries every prefix";
    for (std::size_t size = 0; size < good.size(); ++size) {
      const Bytes prefix(good.begin(), good.begin() + size);
      try {
        deserializeCflModel(prefix.data(), prefix.size(), kName);
        ADD_FAILURE() << "a file truncated to " << size << " bytes loaded";
      } catch (const Error& error) {
        ASSERT_EQ(std::string(error.what()).rfind(kName, 0), 0u) << error.what();
      }
    }
    // Extra bytes at the end are refused as well (a concatenation or a botched copy).
    Bytes longer = good;
    longer.push_back(0);
    expectRefused(longer, "unexpected bytes after the payload");
  }
}

TEST(CflFile, EverySingleByteFlipIsRefused) {
  // CRC-32 detects every error burst of up to 32 bits, so each flipped byte, wherever it is, must be caught.
  test::Rng rng(11);
  for (const CflModel* model : {&smallModel(), &adaptiveModel()}) {
    const Bytes good = serializeCflModel(*model);
    for (std::size_t at = 0; at < good.size(); ++at) {
      Bytes bytes = good;
      bytes[at] ^= static_cast<unsigned char>(1 + rng() % 255);
      try {
        deserializeCflModel(bytes.data(), bytes.size(), kName);
        ADD_FAILURE() << "a file with byte " << at << " changed loaded";
      } catch (const Error& error) {
        ASSERT_EQ(std::string(error.what()).rfind(kName, 0), 0u) << error.what();
      }
    }
  }
}

TEST(CflFile, RandomMultiByteDamageNeverLoadsADifferentModel) {
  const CflModel b = build(test::makeTorus(0.5, 0.2, 12, 6), 6);
  test::Rng rng(5);
  for (const CflModel* model : {&smallModel(), &adaptiveModel()}) {
    const Bytes good = serializeCflModel(*model);
    for (int trial = 0; trial < 1500; ++trial) {
      Bytes bytes = good;
      const int flips = 2 + static_cast<int>(rng() % 8);
      for (int f = 0; f < flips; ++f) bytes[rng() % bytes.size()] ^= static_cast<unsigned char>(1 + rng() % 255);
      try {
        const CflModel loaded = deserializeCflModel(bytes.data(), bytes.size(), kName);
        // Only possible if the damage happened to cancel out; the model must then be the original.
        expectSameModel(*model, loaded);
        expectSameAnswers(*model, loaded, b, 2, trial);
      } catch (const Error&) {
      }
    }
  }
}

// Damaged and then resealed (as a buggy writer would produce), so the checks behind the checksums run: the
// loader must refuse with a cfl::Error or load a model that is structurally sound and can be queried.
TEST(CflFile, ResealedRandomDamageIsRefusedOrLoadsAQueryableModel) {
  const MeshModel b = makeMeshModel(test::makeTorus(0.5, 0.2, 12, 6));
  test::Rng rng(9);
  for (const CflModel* model : {&smallModel(), &adaptiveModel()}) {
    const Bytes good = serializeCflModel(*model);
    int refused = 0;
    for (int trial = 0; trial < 3000; ++trial) {
      Bytes bytes = good;
      const int flips = 1 + static_cast<int>(rng() % 4);
      for (int f = 0; f < flips; ++f) {
        bytes[32 + rng() % (bytes.size() - 32)] ^= static_cast<unsigned char>(1u << (rng() % 8));
      }
      detail::resealCflBuffer(bytes.data(), bytes.size());
      try {
        const CflModel loaded = deserializeCflModel(bytes.data(), bytes.size(), kName);
        for (QueryMode mode : {QueryMode::kHierarchical, QueryMode::kPaper}) {
          DistanceOptions options;
          options.mode = mode;
          const DistanceResult result =
              computeDistance(loaded, Eigen::Isometry3d::Identity(), b, test::randomPose(rng, 3.0), options);
          EXPECT_GE(result.distance, 0.0);
        }
      } catch (const Error& error) {
        ++refused;
        ASSERT_EQ(std::string(error.what()).rfind(kName, 0), 0u) << error.what();
      }
    }
    EXPECT_GT(refused, 0);
  }
}

// A model saved intact, then edited field by field at its documented offset and resealed, so that each
// structural check is reached past the checksum.
class CflFileStructure : public ::testing::Test {
 protected:
  void SetUp() override {
    good_ = serializeCflModel(smallModel());
    adaptive_ = serializeCflModel(adaptiveModel());
  }
  static Bytes edited(const Bytes& good, const std::function<void(Bytes&)>& edit) {
    Bytes bytes = good;
    edit(bytes);
    detail::resealCflBuffer(bytes.data(), bytes.size());
    return bytes;
  }
  Bytes edited(const std::function<void(Bytes&)>& edit) const { return edited(good_, edit); }
  Bytes editedAdaptive(const std::function<void(Bytes&)>& edit) const { return edited(adaptive_, edit); }
  Bytes good_, adaptive_;
};

TEST_F(CflFileStructure, AbsurdCountsAreRefusedWithoutAllocating) {
  // Counts of 2^60 elements would need exabytes: each must be refused before any allocation.
  const std::size_t mesh = sectionBody(good_, "MESH");
  const std::size_t nodes = sectionBody(good_, "NODE");
  const std::size_t leaves = sectionBody(good_, "LEAF");
  const std::size_t list = sectionBody(good_, "LIST");
  const std::size_t entry_bounds = sectionBody(good_, "LBND");
  const std::size_t stat = sectionBody(good_, "STAT");
  const std::uint64_t huge = std::uint64_t(1) << 60;
  expectRefused(edited([&](Bytes& b) { putU64(b, mesh, huge); }), "vertex count");
  expectRefused(edited([&](Bytes& b) { putU64(b, mesh + 8, huge); }), "triangle count");
  expectRefused(edited([&](Bytes& b) { putU64(b, nodes, huge); }), "node count");
  expectRefused(edited([&](Bytes& b) { putU64(b, leaves, huge); }), "leaf count");
  expectRefused(edited([&](Bytes& b) { putU64(b, list, huge); }), "list_offsets size");
  expectRefused(edited([&](Bytes& b) { putU64(b, list + 8, huge); }), "list_triangles size");
  expectRefused(edited([&](Bytes& b) { putU64(b, entry_bounds, huge); }), "list_entry_bounds size");
  expectRefused(edited([&](Bytes& b) { putU64(b, stat + 68, huge); }), "leaves_per_depth size");
  expectRefused(edited([&](Bytes& b) { putU64(b, 16, huge); }), "truncated");
  // A section length past the end of the file.
  expectRefused(edited([&](Bytes& b) { putU64(b, list - 8, huge); }), "runs past the end");
  // Counts that fit the file but do not add up to the section.
  expectRefused(edited([&](Bytes& b) { putU64(b, list + 8, getU64(b, list + 8) - 1); }), "unexpected bytes");
  expectRefused(edited([&](Bytes& b) { putU64(b, nodes, getU64(b, nodes) - 1); }), "unexpected bytes");
  expectRefused(edited([&](Bytes& b) { putU64(b, leaves, getU64(b, leaves) + 1); }), "leaf count");
}

TEST_F(CflFileStructure, ListContentsOutOfRangeOrUnorderedAreRefused) {
  const CflModel& model = smallModel();
  const RegionTree& tree = model.regions;
  const std::size_t list = sectionBody(good_, "LIST");
  const std::size_t offsets = tree.list_offsets.size();
  const std::size_t offsets_at = list + 16, ids_at = offsets_at + 4 * offsets;
  const std::uint32_t triangle_count = static_cast<std::uint32_t>(model.geometry.mesh.triangles.size());

  expectRefused(edited([&](Bytes& b) { putU32(b, ids_at, triangle_count); }),
                "triangle id " + std::to_string(triangle_count) + ", out of range");
  expectRefused(edited([&](Bytes& b) { putU32(b, ids_at, 0xFFFFFFFFu); }), "triangle id -1, out of range");
  expectRefused(edited([&](Bytes& b) { putU32(b, offsets_at, 1); }), "list_offsets[0]");
  ASSERT_GE(offsets, 3u) << "the small model needs at least two lists for this test";
  // Offsets that go backwards.
  expectRefused(edited([&](Bytes& b) { putU32(b, offsets_at + 4, getU32(b, offsets_at + 8) + 1); }), "not increasing");
  expectRefused(edited([&](Bytes& b) { putU32(b, offsets_at + 4 * (offsets - 1), 0); }), "last list offset");
  // An empty list.
  expectRefused(edited([&](Bytes& b) { putU32(b, offsets_at + 4, 0); }), "list 0 is empty");
  // Find a list with two entries at least and swap them.
  std::size_t two = offsets;
  for (std::size_t l = 0; l + 1 < offsets && two == offsets; ++l) {
    if (tree.list_offsets[l + 1] - tree.list_offsets[l] >= 2) two = l;
  }
  ASSERT_LT(two, offsets);
  const std::size_t first = ids_at + 4 * tree.list_offsets[two];
  expectRefused(edited([&](Bytes& b) {
                  const std::uint32_t x = getU32(b, first), y = getU32(b, first + 4);
                  putU32(b, first, y);
                  putU32(b, first + 4, x);
                }),
                "not sorted");
}

TEST_F(CflFileStructure, EntryBoundsAreRequiredAndChecked) {
  const RegionTree& tree = smallModel().regions;
  // Renamed, LBND is an unknown section (skipped), so it is missing.
  expectRefused(edited([&](Bytes& b) { b[sectionBody(b, "LBND") - 16] = 'X'; }), "required section LBND is missing");
  // Bounds out of order inside a list: find a list of two entries or more and raise the first bound.
  const std::size_t body = sectionBody(good_, "LBND");
  std::size_t two = tree.list_offsets.size();
  for (std::size_t l = 0; l + 1 < tree.list_offsets.size(); ++l) {
    if (tree.list_offsets[l + 1] - tree.list_offsets[l] >= 2) {
      two = l;
      break;
    }
  }
  ASSERT_LT(two + 1, tree.list_offsets.size());
  const std::size_t entry = body + 8 + tree.list_offsets[two];
  expectRefused(edited([&](Bytes& b) { b[entry] = static_cast<unsigned char>(std::max<int>(b[entry + 1], 1) + 1); }),
                "not sorted by (entry bound, id)");
  // A count that does not match the lists (the section then ends early: the count is checked first).
  expectRefused(edited([&](Bytes& b) { putU64(b, body, getU64(b, body) - 1); }), "LBND");
  CflModel model = smallModel();
  model.regions.list_entry_bounds.pop_back();
  expectModelRefused(model, "but list_entry_bounds has");
}

TEST_F(CflFileStructure, RootGridInconsistentWithTheNodesIsRefused) {
  const std::size_t tree = sectionBody(good_, "TREE");
  const std::size_t dims = tree + 32;
  expectRefused(edited([&](Bytes& b) { putU32(b, dims, getU32(b, dims) + 1); }), "nodes");
  expectRefused(edited([&](Bytes& b) { putU32(b, dims + 4, 0); }), "root_dims[1] is 0");
  expectRefused(edited([&](Bytes& b) { putU32(b, dims + 8, 0x80000000u); }), "root_dims[2] is -2147483648");
  expectRefused(edited([&](Bytes& b) { putU32(b, tree + 56, 2); }), "unknown flags");
  // Fewer root cells than the file's nodes: the rest are nobody's children.
  expectRefused(edited([&](Bytes& b) { putU32(b, dims + 8, getU32(b, dims + 8) - 1); }), "no node points to it");
}

TEST_F(CflFileStructure, HugeRootDimsAreRefusedWithoutOverflow) {
  // Dims whose product overflows 64 bits must not be multiplied.
  const std::size_t dims = sectionBody(good_, "TREE") + 32;
  expectRefused(edited([&](Bytes& b) {
                  for (int axis = 0; axis < 3; ++axis) putU32(b, dims + 4 * axis, 0x7FFFFFFEu);
                }),
                "root grid of 2147483646 x 2147483646 x 2147483646 cells, but only");
  expectRefused(edited([&](Bytes& b) { putU32(b, dims, 0x7FFFFFFFu); }), "cells, but only");
  expectRefused(edited([&](Bytes& b) { putU32(b, dims + 8, 0x40000000u); }), "cells, but only");
}

// Each invariant of the tree that the query relies on (to stay in bounds, to end, and to keep its fixed
// stack) is refused by name, whether it comes from a file or from a model about to be saved.
TEST_F(CflFileStructure, NodesThatLoopOrShareChildrenAreRefused) {
  const CflModel& good = adaptiveModel();
  const RegionTree& tree = good.regions;
  const std::vector<std::size_t> parents = nodesWhere(tree, false), leaves = nodesWhere(tree, true);
  ASSERT_GE(good.regions.max_depth, 2) << "the adaptive test model must have been refined twice";
  ASSERT_GE(parents.size(), 2u);
  ASSERT_LT(parents[1], std::size_t(tree.rootCount())) << "needs two refined root cells";
  const std::size_t inner = parents.back();  // a node below the roots with children
  ASSERT_GE(inner, std::size_t(tree.rootCount()));

  const auto with = [&](std::size_t node, std::uint32_t value) {
    CflModel model = good;
    model.regions.nodes[node] = value;
    return model;
  };
  const std::string self = "node " + std::to_string(inner) + " points to children at node " + std::to_string(inner) + ", not after itself";
  expectModelRefused(with(inner, std::uint32_t(inner)), self);
  expectModelRefused(with(inner, std::uint32_t(inner - 1)), "not after itself");
  expectModelRefused(with(inner, std::uint32_t(parents[0])), "not after itself");
  // Forward, but into the root cells.
  expectModelRefused(with(0, 1), "node 0 points to children at node 1");
  // Forward, past the end.
  expectModelRefused(with(parents[0], std::uint32_t(tree.nodes.size() - 7)), "past the " + std::to_string(tree.nodes.size()) + " nodes");
  // Two parents, one child block; then two blocks that overlap.
  const std::uint32_t block = tree.nodes[parents[0]];
  expectModelRefused(with(parents[1], block),
                     "node " + std::to_string(block) + " is the child of two parents, nodes " + std::to_string(parents[0]) +
                         " and " + std::to_string(parents[1]));
  expectModelRefused(with(parents[1], block + 1), "is the child of two parents");
  // The same edit in the file itself, at its documented offset.
  const std::size_t nodes_at = sectionBody(adaptive_, "NODE") + 8;
  expectRefused(editedAdaptive([&](Bytes& b) { putU32(b, nodes_at + 4 * parents[1], block); }), "is the child of two parents");
  expectRefused(editedAdaptive([&](Bytes& b) { putU32(b, nodes_at + 4 * inner, std::uint32_t(inner)); }), self);
  // Unreachable nodes after the tree.
  CflModel model = good;
  model.regions.nodes.insert(model.regions.nodes.end(), 8, tree.nodes[leaves[0]]);
  expectModelRefused(model, "node " + std::to_string(tree.nodes.size()) + " is not a root cell and no node points to it");
}

TEST_F(CflFileStructure, LeavesReferencedTwiceOrNeverOrOutOfRangeAreRefused) {
  const CflModel& good = adaptiveModel();
  const RegionTree& tree = good.regions;
  const std::vector<std::size_t> leaves = nodesWhere(tree, true);
  const std::uint32_t leaf_count = static_cast<std::uint32_t>(tree.leafCount());
  const std::uint32_t list_count = static_cast<std::uint32_t>(tree.list_offsets.size() - 1);
  ASSERT_GE(leaves.size(), 2u);

  CflModel model = good;
  model.regions.nodes[leaves[1]] = tree.nodes[leaves[0]];
  expectModelRefused(model, "leaf " + std::to_string(tree.nodes[leaves[0]] & ~RegionTree::kLeafBit) +
                                " is referenced twice (again by node " + std::to_string(leaves[1]) + ")");
  model = good;
  model.regions.nodes[leaves[0]] = RegionTree::kLeafBit | leaf_count;
  expectModelRefused(model, "node " + std::to_string(leaves[0]) + " is leaf " + std::to_string(leaf_count) + ", out of range");
  // A leaf no node names: one more leaf at the end of the leaf arrays.
  model = good;
  model.regions.leaf_list.push_back(0);
  model.regions.leaf_lower_bound.push_back(0);
  model.regions.leaf_corner_distance.push_back({});
  expectModelRefused(model, "leaf " + std::to_string(leaf_count) + " is referenced by no node");
  // Leaf arrays of different lengths.
  model = good;
  model.regions.leaf_lower_bound.pop_back();
  expectSaveRefused(model, "leaf arrays disagree");

  // leaf_list out of range, edited in the file.
  const std::size_t leaf_list_at = sectionBody(adaptive_, "LEAF") + 8;
  expectRefused(editedAdaptive([&](Bytes& b) { putU32(b, leaf_list_at + 4 * 3, list_count); }),
                "leaf_list of leaf 3 is list " + std::to_string(list_count) + ", out of range [0, " +
                    std::to_string(list_count) + ")");
  model = good;
  model.regions.leaf_list.back() = 0x80000000u;
  expectModelRefused(model, "leaf_list of leaf " + std::to_string(leaf_count - 1) + " is list 2147483648");
}

TEST_F(CflFileStructure, TreesDeeperThanTwentyFourLevelsAreRefused) {
  const CflModel& good = adaptiveModel();
  const RegionTree& tree = good.regions;
  // The shallowest leaf, made into a chain down to depth 24, the most forEachLeafInBox's stack holds; and
  // the lower corner of its cell (in root-cell units, found walking down from the roots), towards which
  // the chain shrinks.
  const std::vector<int> depths = nodeDepths(tree);
  std::vector<Eigen::Vector3d> corners(tree.nodes.size());
  for (std::int64_t r = 0; r < tree.rootCount(); ++r) {
    corners[r] = Eigen::Vector3d(double(r % tree.root_dims[0]), double((r / tree.root_dims[0]) % tree.root_dims[1]),
                                 double(r / (std::int64_t(tree.root_dims[0]) * tree.root_dims[1])));
  }
  std::size_t start = tree.nodes.size();
  for (std::size_t n = 0; n < tree.nodes.size(); ++n) {
    if (tree.nodes[n] & RegionTree::kLeafBit) {
      if (start == tree.nodes.size() || depths[n] < depths[start]) start = n;
      continue;
    }
    const double half = 0.5 / double(std::int64_t(1) << depths[n]);
    for (int c = 0; c < 8; ++c) {
      corners[tree.nodes[n] + c] = corners[n] + half * Eigen::Vector3d(c & 1, (c >> 1) & 1, c >> 2);
    }
  }
  const int below = 24 - depths[start];

  // 24 levels: saved, loaded and queried, exactly.
  const CflModel deepest = deepened(good, start, below);
  const Bytes bytes = serializeCflModel(deepest);
  EXPECT_EQ(bytes, writeUnchecked(deepest));
  const CflModel loaded = deserializeCflModel(bytes.data(), bytes.size(), kName);
  EXPECT_EQ(loaded.regions.max_depth, 24);
  const MeshModel b = makeMeshModel(test::makeTorus(0.2, 0.05, 12, 6));
  test::Rng rng(17);
  const Eigen::Vector3d deep_corner = tree.origin + tree.root_size * corners[start];
  const double diagonal = good.geometry.bounds.diagonal();
  std::int64_t shallow_cells = 0, deep_cells = 0;
  for (int i = 0; i < 10; ++i) {
    Eigen::Isometry3d X_WB = test::randomPose(rng, 0.1 * diagonal);
    X_WB.translation() += deep_corner;
    const double truth = bruteForceDistance(good.geometry, Eigen::Isometry3d::Identity(), b, X_WB).distance;
    for (QueryMode mode : {QueryMode::kHierarchical, QueryMode::kPaper}) {
      DistanceOptions options;
      options.mode = mode;
      const DistanceResult deep = computeDistance(loaded, Eigen::Isometry3d::Identity(), b, X_WB, options);
      EXPECT_NEAR(deep.distance, truth, 1e-9 * diagonal) << "pose " << i;
      deep_cells += deep.counters.voxel_tests;
      shallow_cells += computeDistance(good, Eigen::Isometry3d::Identity(), b, X_WB, options).counters.voxel_tests;
    }
  }
  // The queries did walk into the chain (it holds more cells than the leaf it replaced).
  EXPECT_GT(deep_cells, shallow_cells);

  // 25 levels: refused whether max_depth says so or not.
  CflModel deeper = deepened(good, start, below + 1);
  expectModelRefused(deeper, "regions max_depth is 25, must be in [0, 24]");
  deeper.regions.max_depth = 24;
  expectModelRefused(deeper, "at depth 24 has children at depth 25, deeper than max_depth 24");
  // max_depth must be the deepest leaf's depth, not more, not less.
  const std::size_t max_depth_at = sectionBody(adaptive_, "TREE") + 44;
  expectRefused(editedAdaptive([&](Bytes& b) { putU32(b, max_depth_at, std::uint32_t(good.regions.max_depth - 1)); }),
                "deeper than max_depth " + std::to_string(good.regions.max_depth - 1));
  expectRefused(editedAdaptive([&](Bytes& b) { putU32(b, max_depth_at, std::uint32_t(good.regions.max_depth + 1)); }),
                "but the deepest leaf is at depth " + std::to_string(good.regions.max_depth));
  expectRefused(editedAdaptive([&](Bytes& b) { putU32(b, max_depth_at, 0xFFFFFFFFu); }), "max_depth is -1");
  expectRefused(editedAdaptive([&](Bytes& b) { putU32(b, max_depth_at, 1000); }), "max_depth is 1000");
}

TEST_F(CflFileStructure, StatisticsMustAgreeWithTheRegions) {
  const CflModel& good = adaptiveModel();
  const std::size_t stat = sectionBody(adaptive_, "STAT");
  expectRefused(editedAdaptive([&](Bytes& b) { putU64(b, stat + 8, getU64(b, stat + 8) + 1); }),
                "statistics say " + std::to_string(good.statistics.voxel_count + 1) + " leaves");
  expectRefused(editedAdaptive([&](Bytes& b) {
                  putU64(b, stat + 76, getU64(b, stat + 76) + 1);
                  putU64(b, stat + 84, getU64(b, stat + 84) - 1);
                }),
                "statistics say leaves per depth [");
  expectRefused(editedAdaptive([&](Bytes& b) { putU64(b, stat + 16, getU64(b, stat + 16) + 1); }),
                "statistics say " + std::to_string(good.statistics.leaves_without_list + 1) + " leaves without a list");
  expectRefused(editedAdaptive([&](Bytes& b) { putU64(b, stat + 40, getU64(b, stat + 40) + 1); }), "distinct lists");
  expectRefused(editedAdaptive([&](Bytes& b) { putU32(b, stat + 64, 2); }), "unknown statistics flags");
  expectRefused(editedAdaptive([&](Bytes& b) { putF64(b, stat + 24, -1.0); }), "statistics hold a negative");
  expectRefused(editedAdaptive([&](Bytes& b) { putU64(b, stat, 0); }), "statistics hold a negative");
  // The coarsened flag is kept.
  CflModel coarsened = good;
  coarsened.statistics.coarsened = true;
  const Bytes bytes = serializeCflModel(coarsened);
  EXPECT_TRUE(deserializeCflModel(bytes.data(), bytes.size(), kName).statistics.coarsened);
  // One entry too many in leaves_per_depth.
  CflModel longer = good;
  longer.statistics.leaves_per_depth.push_back(0);
  expectModelRefused(longer, "statistics say leaves per depth [");
}

// Every input that once crashed a fuzzer, kept in fuzz/regressions/, must now be refused or load cleanly,
// both as found and resealed (the fuzzer tries both).
TEST(CflFile, FuzzerRegressionInputsAreHandled) {
  const std::filesystem::path directory = std::filesystem::path(CFL_DATA_DIR) / ".." / "fuzz" / "regressions" / "cfl_file_fuzzer";
  ASSERT_TRUE(std::filesystem::is_directory(directory)) << directory;
  int files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(directory)) {
    std::ifstream file(entry.path(), std::ios::binary);
    Bytes bytes((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
    for (bool reseal : {false, true}) {
      if (reseal) detail::resealCflBuffer(bytes.data(), bytes.size());
      try {
        const CflModel model = deserializeCflModel(bytes.data(), bytes.size(), entry.path().string());
        const Bytes saved = serializeCflModel(model);
        EXPECT_EQ(saved, serializeCflModel(deserializeCflModel(saved.data(), saved.size(), "resaved")));
      } catch (const Error& error) {
        EXPECT_EQ(std::string(error.what()).rfind(entry.path().string(), 0), 0u) << error.what();
      }
    }
    ++files;
  }
  EXPECT_GT(files, 0);
}

TEST_F(CflFileStructure, NonFiniteValuesAreRefused) {
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  const std::size_t mesh = sectionBody(good_, "MESH");
  const std::size_t tree = sectionBody(good_, "TREE");
  const std::size_t leaves = sectionBody(good_, "LEAF");
  const std::size_t leaf_count = smallModel().regions.leaf_list.size();
  const std::size_t lower_at = leaves + 8 + 4 * leaf_count;
  expectRefused(edited([&](Bytes& b) { putF64(b, mesh + 16 + 24 * 2 + 8, nan); }), "vertex 2 has a non-finite");
  expectRefused(edited([&](Bytes& b) { putF64(b, tree + 8, inf); }), "regions origin is not finite");
  expectRefused(edited([&](Bytes& b) { putF64(b, tree + 24, nan); }), "root_size is nan");
  expectRefused(edited([&](Bytes& b) { putF64(b, tree + 24, -1.0); }), "root_size is -1");
  expectRefused(edited([&](Bytes& b) { putF64(b, tree + 24, 0.0); }), "root_size is 0");
  expectRefused(edited([&](Bytes& b) { putF64(b, tree + 24, 1e308); }), "far corner is not finite");
  expectRefused(edited([&](Bytes& b) { putF64(b, tree + 48, 0.5); }), "padding");
  expectRefused(edited([&](Bytes& b) { putF64(b, tree + 48, nan); }), "padding");
  expectRefused(edited([&](Bytes& b) { putF32(b, lower_at + 4 * 3, std::numeric_limits<float>::quiet_NaN()); }),
                "leaf_lower_bound of leaf 3 is nan");
  expectRefused(edited([&](Bytes& b) { putF32(b, lower_at + 4 * 3, -0.5f); }), "leaf_lower_bound of leaf 3 is -0.5");
  // The corner distances' unit: a power of two in [2^-16, 1], so that the query's products by it are exact.
  for (double unit : {nan, inf, 0.0, -0.25, 2.0, 0.75, 1.0 / 131072, 3.0 / 65536}) {
    expectRefused(edited([&](Bytes& b) { putF64(b, tree + 60, unit); }), "corner_distance_unit is");
  }
  const std::size_t stat = sectionBody(good_, "STAT");
  expectRefused(edited([&](Bytes& b) { putF64(b, stat + 24, nan); }), "non-finite");
  expectRefused(edited([&](Bytes& b) { putF64(b, stat + 56, inf); }), "non-finite");
}

// Leaves that store no list (RegionTree::kNoList) send the query to the Bvh. Made here from a built model,
// so that the test does not depend on which leaves the builder leaves without one: dropping a leaf's list
// keeps the model exact.
CflModel withoutLists(const CflModel& good, std::uint32_t every) {
  CflModel model = good;
  RegionTree& tree = model.regions;
  for (std::size_t leaf = 0; leaf < tree.leaf_list.size(); leaf += every) {
    if (tree.leaf_list[leaf] == RegionTree::kNoList) continue;
    tree.leaf_list[leaf] = RegionTree::kNoList;
    ++model.statistics.leaves_without_list;
  }
  return model;
}

TEST(CflFile, LeavesWithoutAListRoundTripAndAreChecked) {
  const MeshModel b = makeMeshModel(test::makeTorus(0.2, 0.05, 12, 6));
  for (const CflModel* good : {&smallModel(), &adaptiveModel()}) {
    for (std::uint32_t every : {3u, 1u}) {
      const CflModel model = withoutLists(*good, every);
      const Bytes bytes = serializeCflModel(model);
      EXPECT_EQ(bytes, writeUnchecked(model));
      const CflModel loaded = deserializeCflModel(bytes.data(), bytes.size(), kName);
      expectSameModel(model, loaded);
      EXPECT_EQ(loaded.statistics.leaves_without_list, model.statistics.leaves_without_list);
      test::Rng rng(29);
      const double diagonal = good->geometry.bounds.diagonal();
      for (int i = 0; i < 10; ++i) {
        const Eigen::Isometry3d X_WB = test::randomPose(rng, diagonal);
        const double truth = bruteForceDistance(good->geometry, Eigen::Isometry3d::Identity(), b, X_WB).distance;
        for (QueryMode mode : {QueryMode::kHierarchical, QueryMode::kPaper}) {
          DistanceOptions options;
          options.mode = mode;
          EXPECT_NEAR(computeDistance(loaded, Eigen::Isometry3d::Identity(), b, X_WB, options).distance, truth,
                      1e-9 * diagonal)
              << "every " << every << " pose " << i;
        }
      }
    }
  }
  // No lists at all.
  CflModel none = withoutLists(adaptiveModel(), 1);
  none.regions.list_offsets = {0};
  none.regions.list_entry_ids.clear();
  none.regions.list_high_ids.clear();
  none.regions.list_entry_bounds.clear();
  none.statistics.distinct_lists = 0;
  const Bytes bytes = serializeCflModel(none);
  expectSameModel(none, deserializeCflModel(bytes.data(), bytes.size(), kName));
  none.regions.list_offsets.clear();
  expectModelRefused(none, "list_offsets is empty");
  // A count that disagrees, and a list index that is neither a list nor kNoList.
  CflModel model = withoutLists(adaptiveModel(), 3);
  --model.statistics.leaves_without_list;
  expectModelRefused(model, "leaves without a list, the regions have");
  model = adaptiveModel();
  model.regions.leaf_list[2] = RegionTree::kNoList - 1;
  expectModelRefused(model, "leaf_list of leaf 2 is list 4294967294, out of range");
}

// Values a hostile file may hold that pass every check (finite, in range) but are far from the truth: the
// model loads, and queries must still end with a distance or a cfl::Error (the answer may be wrong; the
// checksum exists to keep such files out), as the fuzzer requires.
TEST(CflFile, ExtremeButValidValuesLoadAndQueryWithoutCrashing) {
  const MeshModel b = makeMeshModel(test::makeTorus(0.2, 0.05, 12, 6));
  const float huge = std::numeric_limits<float>::max();
  for (const CflModel* good : {&smallModel(), &adaptiveModel()}) {
    for (int variant = 0; variant < 3; ++variant) {
      CflModel model = *good;
      RegionTree& tree = model.regions;
      for (std::size_t leaf = 0; leaf < tree.leaf_list.size(); ++leaf) {
        if (variant != 1) tree.leaf_corner_distance[leaf].fill(RegionTree::kCornerDistanceSaturated);
        if (variant == 0) tree.corner_distance_unit = 1;  // the coarsest unit: saturated means 65535 edges
        if (variant != 0) tree.leaf_lower_bound[leaf] = huge;
      }
      if (variant == 2) {  // every entry claims to be far: the lists then go in id order
        std::fill(tree.list_entry_bounds.begin(), tree.list_entry_bounds.end(), std::uint8_t(255));
        ASSERT_TRUE(tree.list_high_ids.empty()) << "a small mesh's lists are narrow: base + 16-bit id";
        for (std::uint32_t l = 0; l < tree.listCount(); ++l) {
          const auto first = tree.list_entry_ids.begin() + std::ptrdiff_t(tree.listIdsBegin(l) + 2);
          std::sort(first, first + tree.listLength(l));
        }
      }
      const Bytes bytes = serializeCflModel(model);
      const CflModel loaded = deserializeCflModel(bytes.data(), bytes.size(), kName);
      test::Rng rng(23);
      for (int i = 0; i < 10; ++i) {
        for (QueryMode mode : {QueryMode::kHierarchical, QueryMode::kPaper}) {
          DistanceOptions options;
          options.mode = mode;
          const Eigen::Isometry3d X_WB = test::randomPose(rng, 2 * good->geometry.bounds.diagonal());
          try {
            const DistanceResult result = computeDistance(loaded, Eigen::Isometry3d::Identity(), b, X_WB, options);
            EXPECT_GE(result.distance, 0.0) << "variant " << variant << " pose " << i;
          } catch (const Error&) {
          }
        }
      }
    }
  }
}

TEST_F(CflFileStructure, MeshDefectsAreNamedAsInValidateMesh) {
  const std::size_t mesh = sectionBody(good_, "MESH");
  const std::size_t vertices = smallModel().geometry.mesh.vertices.size();
  const std::size_t triangles_at = mesh + 16 + 24 * vertices;
  expectRefused(edited([&](Bytes& b) { putU32(b, triangles_at + 12 * 5 + 4, 1000); }), "triangle 5: vertex index 1000");
  expectRefused(edited([&](Bytes& b) { putU32(b, triangles_at, 0xFFFFFFFFu); }), "triangle 0: vertex index -1");
}

TEST_F(CflFileStructure, MissingDuplicateAndUnknownSectionsAreHandled) {
  // Renaming a section makes it unknown: skipped, so it is reported missing.
  for (const char* tag : {"MESH", "TREE", "NODE", "LEAF", "LIST", "LBND", "STAT"}) {
    const std::size_t header = sectionBody(good_, tag) - 16;
    expectRefused(edited([&](Bytes& b) { b[header] = 'X'; }), std::string("required section ") + tag + " is missing");
  }
  // Renaming TREE to MESH makes MESH appear twice; NODE to LEAF, LEAF twice.
  const std::size_t tree = sectionBody(good_, "TREE") - 16;
  expectRefused(edited([&](Bytes& b) { std::memcpy(&b[tree], "MESH", 4); }), "section MESH at byte " + std::to_string(tree) + ": appears twice");
  const std::size_t leaves = sectionBody(good_, "LEAF") - 16;
  expectRefused(edited([&](Bytes& b) { std::memcpy(&b[leaves], "NODE", 4); }), "section NODE at byte " + std::to_string(leaves) + ": appears twice");
  expectRefused(edited([&](Bytes& b) { b[tree + 4] = 1; }), "reserved field");
  // An extra unknown section, as a later writer may add, is skipped; so are the old GRID and BNDS tags.
  for (const char* tag : {"NEXT", "GRID", "BNDS"}) {
    Bytes bytes = good_;
    const Bytes extra = {static_cast<unsigned char>(tag[0]), static_cast<unsigned char>(tag[1]),
                         static_cast<unsigned char>(tag[2]), static_cast<unsigned char>(tag[3]),
                         0, 0, 0, 0, 3, 0, 0, 0, 0, 0, 0, 0, 1, 2, 3};
    bytes.insert(bytes.end(), extra.begin(), extra.end());
    putU64(bytes, 16, bytes.size() - 32);
    detail::resealCflBuffer(bytes.data(), bytes.size());
    expectSameModel(smallModel(), deserializeCflModel(bytes.data(), bytes.size(), kName));
  }
  // Sections in another order load the same model.
  Bytes reordered(good_.begin(), good_.begin() + 32);
  const std::size_t stat = sectionBody(good_, "STAT") - 16;
  reordered.insert(reordered.end(), good_.begin() + static_cast<std::ptrdiff_t>(stat), good_.end());
  reordered.insert(reordered.end(), good_.begin() + 32, good_.begin() + static_cast<std::ptrdiff_t>(stat));
  detail::resealCflBuffer(reordered.data(), reordered.size());
  expectSameModel(smallModel(), deserializeCflModel(reordered.data(), reordered.size(), kName));
}

TEST(CflFile, SavingAModelThatBreaksAnInvariantIsRefused) {
  CflModel model = smallModel();
  // The first list's base, so that its first entry names triangle 1 << 20.
  const std::uint32_t base = (1u << 20) - model.regions.list_entry_ids[2];
  model.regions.list_entry_ids[0] = std::uint16_t(base & 0xffff);
  model.regions.list_entry_ids[1] = std::uint16_t(base >> 16);
  expectModelRefused(model, "triangle id 1048576, out of range");
  model = smallModel();
  model.regions.leaf_corner_distance.pop_back();
  expectSaveRefused(model, "leaf arrays disagree");
  model = adaptiveModel();
  model.regions.nodes.pop_back();
  expectModelRefused(model, "past the");
  model = adaptiveModel();
  model.statistics.leaves_per_depth.clear();
  expectModelRefused(model, "leaves per depth");
  expectSaveRefused(model, "statistics say leaves per depth [], the regions have [");
}

TEST(CflFile, FileSystemErrorsNameThePath) {
  const std::string missing = temporaryPath("cfl_file_test_does_not_exist");
  try {
    loadCflModel(missing);
    ADD_FAILURE() << "loaded a missing file";
  } catch (const Error& error) {
    EXPECT_EQ(std::string(error.what()).rfind(missing, 0), 0u) << error.what();
  }
  const std::string directory = std::filesystem::temp_directory_path().string();
  EXPECT_THROW(loadCflModel(directory), Error);
  const std::string unwritable = directory + "/no_such_directory_for_cfl_test/model.cfl";
  try {
    saveCflModel(smallModel(), unwritable);
    ADD_FAILURE() << "saved into a missing directory";
  } catch (const Error& error) {
    EXPECT_EQ(std::string(error.what()).rfind(unwritable, 0), 0u) << error.what();
  }
  // A file of another kind on disk is refused from its header, before it is read whole.
  const std::string text = temporaryPath("cfl_file_test_text");
  std::ofstream(text) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  try {
    loadCflModel(text);
    ADD_FAILURE() << "loaded a text file";
  } catch (const Error& error) {
    EXPECT_NE(std::string(error.what()).find(text + ": not a CFL model file"), std::string::npos) << error.what();
  }
  std::filesystem::remove(text);
}

}  // namespace
}  // namespace cfl
