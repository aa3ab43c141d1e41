// CFL model files: a loaded model is the saved one (every query answers bit-identically), the bytes follow
// the documented little-endian layout, and every kind of damaged or foreign file is refused with a cfl::Error
// naming the file and the defect - never a crash, a huge allocation or a model that answers differently.

#include "cfl/cfl_file.h"
#include "cfl/cfl_model.h"
#include "cfl/cfl_query.h"
#include "cfl/error.h"
#include "support/test_meshes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <map>
#include <string>
#include <vector>

namespace cfl {
namespace {

using Bytes = std::vector<unsigned char>;
constexpr const char* kName = "model_under_test.cfl";

bool sameBits(double x, double y) { return std::memcmp(&x, &y, sizeof(double)) == 0; }
bool sameBits(const Eigen::Vector3d& x, const Eigen::Vector3d& y) { return std::memcmp(x.data(), y.data(), 24) == 0; }

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

// Field-by-field equality of two models, the derived Bvh included.
void expectSameModel(const CflModel& a, const CflModel& b) {
  ASSERT_EQ(a.geometry.mesh.vertices.size(), b.geometry.mesh.vertices.size());
  for (std::size_t v = 0; v < a.geometry.mesh.vertices.size(); ++v) {
    ASSERT_TRUE(sameBits(a.geometry.mesh.vertices[v], b.geometry.mesh.vertices[v])) << "vertex " << v;
  }
  EXPECT_EQ(a.geometry.mesh.triangles, b.geometry.mesh.triangles);
  ASSERT_EQ(a.geometry.bvh.nodes.size(), b.geometry.bvh.nodes.size());
  for (std::size_t n = 0; n < a.geometry.bvh.nodes.size(); ++n) {
    const BvhNode &x = a.geometry.bvh.nodes[n], &y = b.geometry.bvh.nodes[n];
    ASSERT_TRUE(sameBits(x.box.min, y.box.min) && sameBits(x.box.max, y.box.max) && sameBits(x.center, y.center) &&
                sameBits(x.radius, y.radius) && x.first == y.first && x.count == y.count)
        << "bvh node " << n;
  }
  EXPECT_EQ(a.geometry.bvh.triangle_ids, b.geometry.bvh.triangle_ids);
  EXPECT_TRUE(sameBits(a.grid.origin, b.grid.origin));
  EXPECT_TRUE(sameBits(a.grid.voxel_size, b.grid.voxel_size));
  EXPECT_EQ(a.grid.dims, b.grid.dims);
  EXPECT_TRUE(sameBits(a.padding, b.padding));
  EXPECT_EQ(a.topology_culling, b.topology_culling);
  EXPECT_EQ(a.voxel_list, b.voxel_list);
  EXPECT_EQ(a.list_offsets, b.list_offsets);
  EXPECT_EQ(a.list_triangles, b.list_triangles);
  EXPECT_EQ(a.list_entry_bounds, b.list_entry_bounds);
  EXPECT_EQ(0, std::memcmp(a.voxel_lower_bound.data(), b.voxel_lower_bound.data(), 8 * a.voxel_lower_bound.size()));
  EXPECT_EQ(a.voxel_lower_bound.size(), b.voxel_lower_bound.size());
  EXPECT_EQ(0, std::memcmp(a.corner_distance.data(), b.corner_distance.data(), 8 * a.corner_distance.size()));
  EXPECT_EQ(a.corner_distance.size(), b.corner_distance.size());
  EXPECT_EQ(a.statistics.resolution, b.statistics.resolution);
  EXPECT_EQ(a.statistics.voxel_count, b.statistics.voxel_count);
  EXPECT_EQ(a.statistics.distinct_lists, b.statistics.distinct_lists);
  EXPECT_EQ(a.statistics.longest_list, b.statistics.longest_list);
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
    // Translations from inside A to well outside its padded grid.
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

CflModel build(const TriangleMesh& mesh, int resolution, double padding = 2.0, bool topology_culling = false) {
  BuildOptions options;
  options.resolution = resolution;
  options.padding = padding;
  options.topology_culling = topology_culling;
  return buildCflModel(mesh, options);
}

// A small model (12 triangles, 4^3 voxels), so that every byte offset can be tried.
const CflModel& smallModel() {
  static const CflModel model = build(test::makeBox(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 2, 3)), 4);
  return model;
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
std::uint32_t getU32(const Bytes& bytes, std::size_t at) {
  std::uint32_t value = 0;
  for (int i = 0; i < 4; ++i) value |= std::uint32_t(bytes[at + i]) << (8 * i);
  return value;
}
std::uint64_t getU64(const Bytes& bytes, std::size_t at) {
  return std::uint64_t(getU32(bytes, at)) | std::uint64_t(getU32(bytes, at + 4)) << 32;
}

// Bit-by-bit CRC-32, written from the definition: an independent reference for the library's table version.
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

std::string temporaryPath(const std::string& stem) {
  return (std::filesystem::temp_directory_path() /
          (stem + "_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + ".cfl"))
      .string();
}

TEST(CflFile, LoadedModelAnswersEveryQueryBitIdentically) {
  const CflModel b = build(test::makeTorus(0.5, 0.15, 16, 8), 10);
  struct Case {
    const char* name;
    CflModel model;
  };
  const Case cases[] = {
      {"torus knot", build(test::makeTorusKnot(2, 3, 0.5), 16)},
      {"messy", build(test::makeMessyMesh(), 12, 1.5)},
      {"open hemisphere, topology culling", build(test::makeHemisphere(), 10, 2.0, true)},
      {"triangle soup", build(test::makeTriangleSoup(200, 7), 12, 1.0)},
      {"bunny", build(test::loadBunny(), 20)},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const Bytes bytes = serializeCflModel(c.model);
    const CflModel loaded = deserializeCflModel(bytes.data(), bytes.size(), c.name);
    expectSameModel(c.model, loaded);
    expectSameAnswers(c.model, loaded, b, 12, 42);
    // The format has one encoding per model: saving the loaded model gives the same bytes.
    EXPECT_EQ(bytes, serializeCflModel(loaded));
  }
}

TEST(CflFile, SaveThenLoadThroughTheFileSystemGivesTheSameModel) {
  const CflModel model = build(test::makeTorusKnot(3, 2, 0.4), 12);
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
  const Bytes bytes = serializeCflModel(smallModel());
  ASSERT_GE(bytes.size(), 32u);
  const unsigned char magic[8] = {0x89, 'C', 'F', 'L', '\r', '\n', 0x1A, '\n'};
  EXPECT_EQ(0, std::memcmp(bytes.data(), magic, 8));
  EXPECT_EQ(bytes[8], 0x04);
  EXPECT_EQ(bytes[9], 0x03);
  EXPECT_EQ(bytes[10], 0x02);
  EXPECT_EQ(bytes[11], 0x01);
  EXPECT_EQ(getU32(bytes, 12), kCflFileVersion);
  EXPECT_EQ(getU64(bytes, 16), bytes.size() - 32);
  EXPECT_EQ(getU32(bytes, 24), referenceCrc32(bytes.data() + 32, bytes.size() - 32));
  EXPECT_EQ(getU32(bytes, 28), referenceCrc32(bytes.data(), 28));

  // Sections in the documented order, each holding what the model holds.
  const CflModel& model = smallModel();
  const std::size_t mesh = sectionBody(bytes, "MESH");
  EXPECT_EQ(getU64(bytes, mesh), model.geometry.mesh.vertices.size());
  EXPECT_EQ(getU64(bytes, mesh + 8), model.geometry.mesh.triangles.size());
  double x;
  const std::uint64_t x_bits = getU64(bytes, mesh + 16);
  std::memcpy(&x, &x_bits, 8);
  EXPECT_TRUE(sameBits(x, model.geometry.mesh.vertices[0].x()));
  const std::size_t grid = sectionBody(bytes, "GRID");
  EXPECT_EQ(static_cast<int>(getU32(bytes, grid + 32)), model.grid.dims[0]);
  const std::size_t list = sectionBody(bytes, "LIST");
  EXPECT_EQ(getU64(bytes, list), model.voxel_list.size());
  EXPECT_EQ(getU64(bytes, list + 8), model.list_offsets.size());
  EXPECT_EQ(getU64(bytes, list + 16), model.list_triangles.size());
  const std::size_t bounds = sectionBody(bytes, "BNDS");
  EXPECT_EQ(getU64(bytes, bounds + 8), model.corner_distance.size());
  EXPECT_LT(mesh, grid);
  EXPECT_LT(grid, list);
  EXPECT_LT(list, bounds);
  EXPECT_LT(bounds, sectionBody(bytes, "STAT"));
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
  const Bytes good = serializeCflModel(smallModel());
  ASSERT_LT(good.size(), 100000u) << "the small model grew; this test tries every prefix";
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

TEST(CflFile, EverySingleByteFlipIsRefused) {
  // CRC-32 detects every error burst of up to 32 bits, so each flipped byte, wherever it is, must be caught.
  const Bytes good = serializeCflModel(smallModel());
  test::Rng rng(11);
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

TEST(CflFile, RandomMultiByteDamageNeverLoadsADifferentModel) {
  const CflModel& model = smallModel();
  const Bytes good = serializeCflModel(model);
  const CflModel b = build(test::makeTorus(0.5, 0.2, 12, 6), 6);
  test::Rng rng(5);
  for (int trial = 0; trial < 3000; ++trial) {
    Bytes bytes = good;
    const int flips = 2 + static_cast<int>(rng() % 8);
    for (int f = 0; f < flips; ++f) bytes[rng() % bytes.size()] ^= static_cast<unsigned char>(1 + rng() % 255);
    try {
      const CflModel loaded = deserializeCflModel(bytes.data(), bytes.size(), kName);
      // Only possible if the damage happened to cancel out; the model must then be the original.
      expectSameModel(model, loaded);
      expectSameAnswers(model, loaded, b, 2, trial);
    } catch (const Error&) {
    }
  }
}

// Damaged and then resealed (as a buggy writer would produce), so the checks behind the checksums run: the
// loader must refuse with a cfl::Error or load a model that is structurally sound and can be queried.
TEST(CflFile, ResealedRandomDamageIsRefusedOrLoadsAQueryableModel) {
  const Bytes good = serializeCflModel(smallModel());
  const MeshModel b = makeMeshModel(test::makeTorus(0.5, 0.2, 12, 6));
  test::Rng rng(9);
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
      const DistanceResult result =
          computeDistance(loaded, Eigen::Isometry3d::Identity(), b, test::randomPose(rng, 3.0));
      EXPECT_GE(result.distance, 0.0);
    } catch (const Error& error) {
      ++refused;
      ASSERT_EQ(std::string(error.what()).rfind(kName, 0), 0u) << error.what();
    }
  }
  EXPECT_GT(refused, 0);
}

// A model saved intact, then edited field by field at its documented offset and resealed, so that each
// structural check is reached past the checksum.
class CflFileStructure : public ::testing::Test {
 protected:
  void SetUp() override { good_ = serializeCflModel(smallModel()); }
  Bytes edited(const std::function<void(Bytes&)>& edit) const {
    Bytes bytes = good_;
    edit(bytes);
    detail::resealCflBuffer(bytes.data(), bytes.size());
    return bytes;
  }
  Bytes good_;
};

TEST_F(CflFileStructure, AbsurdCountsAreRefusedWithoutAllocating) {
  // Counts of 2^60 elements would need exabytes: each must be refused before any allocation.
  const std::size_t mesh = sectionBody(good_, "MESH");
  const std::size_t list = sectionBody(good_, "LIST");
  const std::size_t bounds = sectionBody(good_, "BNDS");
  const std::uint64_t huge = std::uint64_t(1) << 60;
  expectRefused(edited([&](Bytes& b) { putU64(b, mesh, huge); }), "vertex count");
  expectRefused(edited([&](Bytes& b) { putU64(b, mesh + 8, huge); }), "triangle count");
  expectRefused(edited([&](Bytes& b) { putU64(b, list, huge); }), "voxel_list size");
  expectRefused(edited([&](Bytes& b) { putU64(b, list + 16, huge); }), "list_triangles size");
  expectRefused(edited([&](Bytes& b) { putU64(b, bounds + 8, huge); }), "corner_distance size");
  expectRefused(edited([&](Bytes& b) { putU64(b, 16, huge); }), "truncated");
  // A section length past the end of the file.
  expectRefused(edited([&](Bytes& b) { putU64(b, list - 8, huge); }), "runs past the end");
  // Counts that fit the file but do not add up to the section.
  expectRefused(edited([&](Bytes& b) { putU64(b, list + 16, getU64(b, list + 16) - 1); }), "unexpected bytes");
}

TEST_F(CflFileStructure, ListContentsOutOfRangeOrUnorderedAreRefused) {
  const CflModel& model = smallModel();
  const std::size_t list = sectionBody(good_, "LIST");
  const std::size_t voxels = model.voxel_list.size(), offsets = model.list_offsets.size();
  const std::size_t voxel_list_at = list + 24, offsets_at = voxel_list_at + 4 * voxels,
                    ids_at = offsets_at + 4 * offsets;
  const std::uint32_t triangle_count = static_cast<std::uint32_t>(model.geometry.mesh.triangles.size());

  expectRefused(edited([&](Bytes& b) { putU32(b, ids_at, triangle_count); }),
                "triangle id " + std::to_string(triangle_count) + ", out of range");
  expectRefused(edited([&](Bytes& b) { putU32(b, ids_at, 0xFFFFFFFFu); }), "triangle id -1, out of range");
  expectRefused(edited([&](Bytes& b) { putU32(b, voxel_list_at + 4, static_cast<std::uint32_t>(offsets)); }),
                "voxel 1 refers to list");
  expectRefused(edited([&](Bytes& b) { putU32(b, offsets_at, 1); }), "list_offsets[0]");
  ASSERT_GE(offsets, 3u) << "the small model needs at least two lists for this test";
  // Offsets that go backwards.
  expectRefused(edited([&](Bytes& b) { putU32(b, offsets_at + 4, getU32(b, offsets_at + 8) + 1); }), "not increasing");
  expectRefused(edited([&](Bytes& b) { putU32(b, offsets_at + 4 * (offsets - 1), 0); }), "last list offset");
  // Find a list with two entries at least and swap them.
  std::size_t two = offsets;
  for (std::size_t l = 0; l + 1 < offsets && two == offsets; ++l) {
    if (model.list_offsets[l + 1] - model.list_offsets[l] >= 2) two = l;
  }
  ASSERT_LT(two, offsets);
  const std::size_t first = ids_at + 4 * model.list_offsets[two];
  expectRefused(edited([&](Bytes& b) {
                  const std::uint32_t x = getU32(b, first), y = getU32(b, first + 4);
                  putU32(b, first, y);
                  putU32(b, first + 4, x);
                }),
                "not sorted");
}

TEST_F(CflFileStructure, GridInconsistentWithArraysIsRefused) {
  const std::size_t grid = sectionBody(good_, "GRID");
  const std::size_t dims = grid + 32;
  expectRefused(edited([&](Bytes& b) { putU32(b, dims, getU32(b, dims) + 1); }), "voxel_list has");
  expectRefused(edited([&](Bytes& b) { putU32(b, dims + 4, 0); }), "dims[1] is 0");
  expectRefused(edited([&](Bytes& b) { putU32(b, dims + 8, 0x80000000u); }), "dims[2] is -2147483648");
  expectRefused(edited([&](Bytes& b) { putU32(b, dims + 12 + 8, 2); }), "unknown flags");
}

TEST_F(CflFileStructure, HugeGridDimsAreRefusedWithoutOverflow) {
  // Found by cfl_file_fuzzer: dims whose product overflows 64 bits must not be multiplied.
  const std::size_t dims = sectionBody(good_, "GRID") + 32;
  expectRefused(edited([&](Bytes& b) {
                  for (int axis = 0; axis < 3; ++axis) putU32(b, dims + 4 * axis, 0x7FFFFFFEu);
                }),
                "grid of 2147483646 x 2147483646 x 2147483646 voxels");
  expectRefused(edited([&](Bytes& b) { putU32(b, dims, 0x7FFFFFFFu); }), "dims[0] is 2147483647");
  expectRefused(edited([&](Bytes& b) { putU32(b, dims + 8, 0x40000000u); }), "voxel_list has");
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
  const std::size_t grid = sectionBody(good_, "GRID");
  const std::size_t bounds = sectionBody(good_, "BNDS");
  const std::size_t voxels = smallModel().voxel_list.size();
  expectRefused(edited([&](Bytes& b) { putF64(b, mesh + 16 + 24 * 2 + 8, nan); }), "vertex 2 has a non-finite");
  expectRefused(edited([&](Bytes& b) { putF64(b, grid + 8, inf); }), "grid origin is not finite");
  expectRefused(edited([&](Bytes& b) { putF64(b, grid + 24, nan); }), "voxel size");
  expectRefused(edited([&](Bytes& b) { putF64(b, grid + 24, -1.0); }), "voxel size");
  expectRefused(edited([&](Bytes& b) { putF64(b, grid + 24, 1e308); }), "far corner is not finite");
  expectRefused(edited([&](Bytes& b) { putF64(b, grid + 44, 0.5); }), "padding");
  expectRefused(edited([&](Bytes& b) { putF64(b, bounds + 16 + 8 * 3, nan); }), "voxel_lower_bound of voxel 3");
  expectRefused(edited([&](Bytes& b) { putF64(b, bounds + 16 + 8 * voxels, -inf); }), "corner_distance of corner 0");
}

TEST_F(CflFileStructure, MeshDefectsAreNamedAsInValidateMesh) {
  const std::size_t mesh = sectionBody(good_, "MESH");
  const std::size_t vertices = smallModel().geometry.mesh.vertices.size();
  const std::size_t triangles_at = mesh + 16 + 24 * vertices;
  expectRefused(edited([&](Bytes& b) { putU32(b, triangles_at + 12 * 5 + 4, 1000); }), "triangle 5: vertex index 1000");
  expectRefused(edited([&](Bytes& b) { putU32(b, triangles_at, 0xFFFFFFFFu); }), "triangle 0: vertex index -1");
}

TEST_F(CflFileStructure, MissingDuplicateAndUnknownSectionsAreHandled) {
  // Renaming the statistics section makes it unknown: skipped, so STAT is reported missing.
  const std::size_t stat = sectionBody(good_, "STAT") - 16;
  expectRefused(edited([&](Bytes& b) { b[stat] = 'X'; }), "required section STAT is missing");
  // Renaming GRID to MESH makes MESH appear twice.
  const std::size_t grid = sectionBody(good_, "GRID") - 16;
  expectRefused(edited([&](Bytes& b) { std::memcpy(&b[grid], "MESH", 4); }), "appears twice");
  expectRefused(edited([&](Bytes& b) { b[grid + 4] = 1; }), "reserved field");
  // An extra unknown section, as a later writer may add, is skipped.
  Bytes bytes = good_;
  const Bytes extra = {'N', 'E', 'X', 'T', 0, 0, 0, 0, 3, 0, 0, 0, 0, 0, 0, 0, 1, 2, 3};
  bytes.insert(bytes.end(), extra.begin(), extra.end());
  putU64(bytes, 16, bytes.size() - 32);
  detail::resealCflBuffer(bytes.data(), bytes.size());
  expectSameModel(smallModel(), deserializeCflModel(bytes.data(), bytes.size(), kName));
}

// A version-1 file: the same sections without LBND, lists sorted by id. Made from `model` after clearing its
// entry bounds (which keeps it valid once its lists are sorted by id).
Bytes versionOneBytes(CflModel& model) {
  for (std::size_t l = 0; l + 1 < model.list_offsets.size(); ++l) {
    std::sort(model.list_triangles.begin() + model.list_offsets[l], model.list_triangles.begin() + model.list_offsets[l + 1]);
  }
  std::fill(model.list_entry_bounds.begin(), model.list_entry_bounds.end(), 0);
  Bytes bytes = serializeCflModel(model);
  const std::size_t body = sectionBody(bytes, "LBND");
  const std::size_t length = 16 + getU64(bytes, body - 8);
  bytes.erase(bytes.begin() + static_cast<std::ptrdiff_t>(body - 16), bytes.begin() + static_cast<std::ptrdiff_t>(body - 16 + length));
  putU32(bytes, 12, 1);
  putU64(bytes, 16, bytes.size() - 32);
  detail::resealCflBuffer(bytes.data(), bytes.size());
  return bytes;
}

TEST(CflFile, VersionOneFilesLoadWithZeroEntryBoundsAndAnswerExactly) {
  CflModel model = build(test::makeTorusKnot(), 7);
  CflModel expected = model;
  const Bytes bytes = versionOneBytes(expected);
  const CflModel loaded = deserializeCflModel(bytes.data(), bytes.size(), kName);
  expectSameModel(expected, loaded);
  for (std::uint8_t bound : loaded.list_entry_bounds) ASSERT_EQ(bound, 0);
  // Bounds of 0 only make the query scan whole lists: the answers stay exact.
  test::Rng rng(11);
  const double diagonal = model.geometry.bounds.diagonal();
  for (int i = 0; i < 20; ++i) {
    const Eigen::Isometry3d X_WB = test::randomPose(rng, (0.2 + 0.1 * (i % 5)) * diagonal);
    const double truth = bruteForceDistance(model.geometry, Eigen::Isometry3d::Identity(), model.geometry, X_WB).distance;
    EXPECT_NEAR(computeDistance(loaded, Eigen::Isometry3d::Identity(), model.geometry, X_WB).distance, truth, 1e-9 * diagonal);
    EXPECT_NEAR(computeDistance(model, Eigen::Isometry3d::Identity(), model.geometry, X_WB).distance, truth, 1e-9 * diagonal);
  }
}

TEST(CflFile, EntryBoundsSectionIsRequiredAndChecked) {
  CflModel model = smallModel();
  // A version-2 file without LBND.
  Bytes bytes = versionOneBytes(model);
  putU32(bytes, 12, 2);
  detail::resealCflBuffer(bytes.data(), bytes.size());
  expectRefused(bytes, "required section LBND is missing");
  // Bounds out of order inside a list: find a list of two entries or more and raise the first bound.
  const Bytes good = serializeCflModel(smallModel());
  const std::size_t body = sectionBody(good, "LBND");
  std::size_t two = smallModel().list_offsets.size();
  for (std::size_t l = 0; l + 1 < smallModel().list_offsets.size(); ++l) {
    if (smallModel().list_offsets[l + 1] - smallModel().list_offsets[l] >= 2) {
      two = l;
      break;
    }
  }
  ASSERT_LT(two + 1, smallModel().list_offsets.size());
  Bytes unsorted = good;
  const std::size_t entry = body + 8 + smallModel().list_offsets[two];
  unsorted[entry] = static_cast<unsigned char>(std::max<int>(unsorted[entry + 1], 1) + 1);
  detail::resealCflBuffer(unsorted.data(), unsorted.size());
  expectRefused(unsorted, "not sorted by (entry bound, id)");
  // A count that does not match the lists.
  Bytes short_count = good;
  putU64(short_count, body, getU64(good, body) - 1);
  detail::resealCflBuffer(short_count.data(), short_count.size());
  expectRefused(short_count, "LBND");
}

TEST(CflFile, SavingAModelThatBreaksAnInvariantIsRefused) {
  CflModel model = smallModel();
  model.list_triangles[0] = 1 << 20;
  EXPECT_THROW(serializeCflModel(model), Error);
  model = smallModel();
  model.voxel_lower_bound.pop_back();
  EXPECT_THROW(serializeCflModel(model), Error);
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
