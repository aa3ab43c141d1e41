// Thread safety: queries on shared const models from many threads at once give exactly the serial answers,
// and the batch API gives exactly the serial answers for every thread count and chunk size. Run under
// ThreadSanitizer by .ci/sanitize.sh, which also catches races that happen not to change a result.

#include "cfl/batch_query.h"
#include "cfl/cfl_file.h"
#include "cfl/cfl_model.h"
#include "cfl/cfl_query.h"
#include "cfl/error.h"
#include "support/test_meshes.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <atomic>
#include <cstring>
#include <limits>
#include <string>
#include <thread>
#include <vector>

namespace cfl {
namespace {

bool sameBits(double x, double y) { return std::memcmp(&x, &y, sizeof(double)) == 0; }
bool sameBits(const Eigen::Vector3d& x, const Eigen::Vector3d& y) { return std::memcmp(x.data(), y.data(), 24) == 0; }

bool sameAnswer(const DistanceResult& x, const DistanceResult& y) {
  return sameBits(x.distance, y.distance) && sameBits(x.point_a, y.point_a) && sameBits(x.point_b, y.point_b) &&
         x.triangle_a == y.triangle_a && x.triangle_b == y.triangle_b &&
         x.counters.triangle_pairs == y.counters.triangle_pairs && x.counters.voxel_tests == y.counters.voxel_tests;
}

// Shared fixtures: built once, then only read, by every test and thread.
struct Scene {
  CflModel a;
  CflModel b_cfl;
  MeshModel b;
  Eigen::Isometry3d X_WA;
  std::vector<Eigen::Isometry3d> poses;  // X_WB, from overlapping to far outside A's grid
};

const Scene& scene() {
  static const Scene s = [] {
    Scene scene;
    BuildOptions options;
    options.resolution = 14;
    scene.a = buildCflModel(test::makeTorusKnot(2, 3, 0.5), options);
    options.resolution = 8;
    scene.b_cfl = buildCflModel(test::makeMessyMesh(), options);
    scene.b = scene.b_cfl.geometry;
    test::Rng rng(2024);
    scene.X_WA = test::randomPose(rng, 0.5);
    const double range = scene.a.geometry.bounds.diagonal();
    for (int i = 0; i < 48; ++i) scene.poses.push_back(test::randomPose(rng, (0.1 + 0.05 * i) * range));
    return scene;
  }();
  return s;
}

std::vector<DistanceResult> serialAnswers(const DistanceOptions& options) {
  const Scene& s = scene();
  std::vector<DistanceResult> results;
  for (const auto& X_WB : s.poses) results.push_back(computeDistance(s.a, s.X_WA, s.b, X_WB, options));
  return results;
}

TEST(Concurrency, SerialAnswersAreExactAgainstBruteForce) {
  // Anchors the comparisons below: the answers every thread must reproduce are the exact distances.
  const Scene& s = scene();
  const double tolerance = 1e-9 * (s.a.geometry.bounds.diagonal() + s.b.bounds.diagonal());
  const std::vector<DistanceResult> serial = serialAnswers({});
  for (std::size_t i = 0; i < s.poses.size(); i += 6) {
    EXPECT_NEAR(serial[i].distance, bruteForceDistance(s.a.geometry, s.X_WA, s.b, s.poses[i]).distance, tolerance)
        << "pose " << i;
  }
}

TEST(Concurrency, ThreadsQueryingSharedModelsAgreeWithSerialAnswers) {
  const Scene& s = scene();
  DistanceOptions paper;
  paper.mode = QueryMode::kPaper;
  const std::vector<DistanceResult> serial = serialAnswers({});
  const std::vector<DistanceResult> serial_paper = serialAnswers(paper);
  std::vector<DistanceResult> serial_cfl, serial_reversed;
  std::vector<bool> serial_collision;
  for (const auto& X_WB : s.poses) {
    serial_cfl.push_back(computeDistance(s.a, s.X_WA, s.b_cfl, X_WB));
    serial_reversed.push_back(computeDistance(s.b_cfl, X_WB, s.a, s.X_WA));
    serial_collision.push_back(computeCollision(s.a.geometry, s.X_WA, s.b, X_WB));
  }

  // Every thread runs every kind of query on every pose, each starting at a different pose so that
  // different queries overlap in time; each repeats the sweep so its thread-local scratch is reused.
  constexpr int kThreads = 6;
  std::atomic<int> mismatches{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      const std::size_t n = s.poses.size();
      for (int sweep = 0; sweep < 2; ++sweep) {
        for (std::size_t k = 0; k < n; ++k) {
          const std::size_t i = (k * (t + 1) + 7 * t) % n;
          const auto& X_WB = s.poses[i];
          if (!sameAnswer(serial[i], computeDistance(s.a, s.X_WA, s.b, X_WB))) ++mismatches;
          if (!sameAnswer(serial_paper[i], computeDistance(s.a, s.X_WA, s.b, X_WB, paper))) ++mismatches;
          if (!sameAnswer(serial_cfl[i], computeDistance(s.a, s.X_WA, s.b_cfl, X_WB))) ++mismatches;
          if (!sameAnswer(serial_reversed[i], computeDistance(s.b_cfl, X_WB, s.a, s.X_WA))) ++mismatches;
          if (serial_collision[i] != computeCollision(s.a.geometry, s.X_WA, s.b, X_WB)) ++mismatches;
        }
      }
    });
  }
  for (auto& thread : threads) thread.join();
  EXPECT_EQ(mismatches.load(), 0);
}

TEST(Concurrency, BatchAnswersAreTheSerialAnswersForEveryThreadCountAndChunkSize) {
  const Scene& s = scene();
  for (QueryMode mode : {QueryMode::kHierarchical, QueryMode::kPaper}) {
    DistanceOptions distance;
    distance.mode = mode;
    const std::vector<DistanceResult> serial = serialAnswers(distance);
    for (int threads : {0, 1, 2, 3, 7}) {
      for (int chunk : {0, 1, 5, 1000}) {
        BatchOptions options;
        options.distance = distance;
        options.threads = threads;
        options.chunk_size = chunk;
        const std::vector<DistanceResult> batch = computeDistances(s.a, s.X_WA, s.b, s.poses, options);
        ASSERT_EQ(batch.size(), serial.size());
        for (std::size_t i = 0; i < serial.size(); ++i) {
          EXPECT_TRUE(sameAnswer(serial[i], batch[i]))
              << "pose " << i << ", threads " << threads << ", chunk " << chunk << ": " << serial[i].distance
              << " vs " << batch[i].distance;
        }
      }
    }
  }
  // The CflModel-CflModel overload.
  std::vector<DistanceResult> batch(s.poses.size());
  BatchOptions options;
  options.threads = 3;
  computeDistances(s.a, s.X_WA, s.b_cfl, s.poses.data(), s.poses.size(), batch.data(), options);
  for (std::size_t i = 0; i < s.poses.size(); ++i) {
    EXPECT_TRUE(sameAnswer(computeDistance(s.a, s.X_WA, s.b_cfl, s.poses[i]), batch[i])) << "pose " << i;
  }
}

// Batches started from several threads at once, each in its own TBB arena on TBB's shared workers, and a
// batch under a tbb::global_control that allows one thread: every one gives the serial answers, and the
// thread count reported follows the caps BatchOptions::threads documents.
TEST(Concurrency, ConcurrentBatchesAndAOneThreadLimitGiveTheSerialAnswers) {
  const Scene& s = scene();
  const std::vector<DistanceResult> serial = serialAnswers({});
  std::atomic<int> mismatches{0};
  std::vector<std::thread> callers;
  for (int t = 0; t < 3; ++t) {
    callers.emplace_back([&, t] {
      BatchOptions options;
      options.threads = t + 1;
      options.chunk_size = 1 + 3 * t;
      const std::vector<DistanceResult> batch = computeDistances(s.a, s.X_WA, s.b, s.poses, options);
      for (std::size_t i = 0; i < serial.size(); ++i) mismatches += !sameAnswer(serial[i], batch[i]);
    });
  }
  for (auto& caller : callers) caller.join();
  EXPECT_EQ(mismatches.load(), 0);

  EXPECT_EQ(batchThreadCount(4, 3), std::min(3, batchThreadCount(4, 1000)));
  EXPECT_EQ(batchThreadCount(0, 1), 1);
  {
    const tbb::global_control one_thread(tbb::global_control::max_allowed_parallelism, 1);
    EXPECT_EQ(batchThreadCount(0, 1000), 1);
    EXPECT_EQ(batchThreadCount(8, 1000), 1);
    BatchOptions options;
    options.threads = 8;
    const std::vector<DistanceResult> batch = computeDistances(s.a, s.X_WA, s.b, s.poses, options);
    for (std::size_t i = 0; i < serial.size(); ++i) EXPECT_TRUE(sameAnswer(serial[i], batch[i])) << "pose " << i;
  }
}

TEST(Concurrency, BatchRefusesABadPoseByIndexBeforeAnyWork) {
  const Scene& s = scene();
  std::vector<Eigen::Isometry3d> poses = s.poses;
  poses[5].linear() *= 1.01;  // no longer orthonormal
  std::vector<DistanceResult> results(poses.size());
  results[0].triangle_a = 12345;  // a sentinel that work on pose 0 would overwrite
  try {
    computeDistances(s.a, s.X_WA, s.b, poses.data(), poses.size(), results.data());
    ADD_FAILURE() << "a non-orthonormal pose was accepted";
  } catch (const Error& error) {
    EXPECT_NE(std::string(error.what()).find("X_WB[5]"), std::string::npos) << error.what();
  }
  EXPECT_EQ(results[0].triangle_a, 12345);
  poses = s.poses;
  poses[0].translation().x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(computeDistances(s.a, s.X_WA, s.b, poses), Error);
  // An empty batch is valid and does nothing.
  EXPECT_TRUE(computeDistances(s.a, s.X_WA, s.b, std::vector<Eigen::Isometry3d>{}).empty());
}

TEST(Concurrency, ConcurrentLoadsOfOneBufferGiveIdenticalModels) {
  const Scene& s = scene();
  const std::vector<unsigned char> bytes = serializeCflModel(s.a);
  constexpr int kThreads = 4;
  std::vector<std::vector<unsigned char>> reserialized(kThreads);
  std::vector<DistanceResult> answers(kThreads);
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      const CflModel loaded = deserializeCflModel(bytes.data(), bytes.size(), "shared buffer");
      reserialized[t] = serializeCflModel(loaded);
      answers[t] = computeDistance(loaded, s.X_WA, s.b, s.poses[t]);
    });
  }
  for (auto& thread : threads) thread.join();
  for (int t = 0; t < kThreads; ++t) {
    EXPECT_EQ(reserialized[t], bytes) << "thread " << t;
    EXPECT_TRUE(sameAnswer(answers[t], computeDistance(s.a, s.X_WA, s.b, s.poses[t]))) << "thread " << t;
  }
}

}  // namespace
}  // namespace cfl
