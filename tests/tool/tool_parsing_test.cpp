// Parsing in the cfl tool: pose files, the distance CSV, options and lists. Good input reads back exactly;
// bad input gets an error naming the line (or option, or item) at fault.

#include "cfl/error.h"
#include "measure.h"
#include "pose_file.h"
#include "support/test_meshes.h"
#include "tool_args.h"

#include <gtest/gtest.h>

#include <set>
#include <sstream>
#include <utility>

namespace cfl::tool {
namespace {

// Runs `f`, which must throw E, and returns the message.
template <typename E, typename F>
std::string messageOf(F&& f) {
  try {
    f();
  } catch (const E& e) {
    return e.what();
  }
  ADD_FAILURE() << "no exception";
  return "";
}

std::vector<Eigen::Isometry3d> posesFrom(const std::string& text, const std::string& source = "poses.txt") {
  std::istringstream in(text);
  return readPoses(in, source);
}

constexpr const char* kIdentityLine = "1 0 0 0 0 1 0 0 0 0 1 0";

TEST(PoseFileTest, FormattedPosesReadBackBitIdentically) {
  test::Rng rng(11);
  std::vector<Eigen::Isometry3d> poses;
  std::string text;
  for (int i = 0; i < 50; ++i) {
    poses.push_back(test::randomPose(rng, 100.0));
    text += formatPose(poses.back()) + "\n";
  }
  const auto read = posesFrom(text);
  ASSERT_EQ(read.size(), poses.size());
  for (std::size_t i = 0; i < poses.size(); ++i) {
    EXPECT_EQ(read[i].matrix(), poses[i].matrix()) << "pose " << i;
  }
}

TEST(PoseFileTest, CommentsBlankLinesCommasTabsAndCrlfAreAccepted) {
  const std::string text =
      "# header comment\n"
      "\n"
      "1,0,0,5, 0,1,0,6, 0,0,1,7   # trailing comment\r\n"
      "   \t  \n"
      "0\t-1\t0\t1\t1\t0\t0\t2\t0\t0\t1\t3\n";
  const auto poses = posesFrom(text);
  ASSERT_EQ(poses.size(), 2u);
  EXPECT_EQ(poses[0].translation(), Eigen::Vector3d(5, 6, 7));
  EXPECT_EQ(poses[0].linear(), Eigen::Matrix3d::Identity());
  Eigen::Matrix3d R;
  R << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  EXPECT_EQ(poses[1].linear(), R);
  EXPECT_EQ(poses[1].translation(), Eigen::Vector3d(1, 2, 3));
}

TEST(PoseFileTest, InputWithoutPosesGivesNone) {
  EXPECT_TRUE(posesFrom("").empty());
  EXPECT_TRUE(posesFrom("# nothing\n\n  \n").empty());
}

TEST(PoseFileTest, WrongNumberCountNamesTheLine) {
  const std::string text = std::string("# poses\n") + kIdentityLine + "\n1 0 0 0 0 1 0 0 0 0 1\n";
  const std::string message = messageOf<Error>([&] { posesFrom(text); });
  EXPECT_NE(message.find("poses.txt:3:"), std::string::npos) << message;
  EXPECT_NE(message.find("found 11"), std::string::npos) << message;
  EXPECT_NE(messageOf<Error>([&] { posesFrom(std::string(kIdentityLine) + " 9\n"); }).find("poses.txt:1:"),
            std::string::npos);
}

TEST(PoseFileTest, NonNumbersAndNonFiniteValuesNameTheLineAndWord) {
  for (const std::string bad : {"x", "nan", "inf", "-inf", "1e999", "1.0.0", "0x"}) {
    const std::string text = std::string(kIdentityLine) + "\n\n1 0 0 " + bad + " 0 1 0 0 0 0 1 0\n";
    const std::string message = messageOf<Error>([&] { posesFrom(text, "in.txt"); });
    EXPECT_NE(message.find("in.txt:3:"), std::string::npos) << bad << ": " << message;
    EXPECT_NE(message.find("number 4"), std::string::npos) << bad << ": " << message;
    EXPECT_NE(message.find("'" + bad + "'"), std::string::npos) << bad << ": " << message;
  }
}

TEST(PoseFileTest, NonRigidMatricesNameTheLine) {
  for (const std::string bad : {"2 0 0 0 0 1 0 0 0 0 1 0",      // scaled
                                "1 0 0 0 0 1 0 0 0 0 -1 0",     // reflection (det -1)
                                "1 0.1 0 0 0 1 0 0 0 0 1 0",    // sheared
                                "0 0 0 0 0 0 0 0 0 0 0 0"}) {  // all zero
    const std::string message = messageOf<Error>([&] { posesFrom(std::string(kIdentityLine) + "\n" + bad + "\n"); });
    EXPECT_NE(message.find("poses.txt:2:"), std::string::npos) << bad << ": " << message;
    EXPECT_NE(message.find("rigid"), std::string::npos) << bad << ": " << message;
  }
}

DistanceRow randomRow(test::Rng& rng, long pose, const std::string& method) {
  std::uniform_real_distribution<double> u(-1e3, 1e3);
  DistanceRow row;
  row.pose = pose;
  row.distance = std::abs(u(rng)) * 1e-3;
  row.point_a = Eigen::Vector3d(u(rng), u(rng), u(rng));
  row.point_b = Eigen::Vector3d(u(rng), u(rng), u(rng));
  row.triangle_a = int(rng() % 100000);
  row.triangle_b = int(rng() % 100000);
  row.micros = std::round(std::abs(u(rng)) * 1000) / 1000;  // printed with 3 decimals
  row.method = method;
  return row;
}

TEST(DistanceCsvTest, FormattedRowsReadBackExactly) {
  test::Rng rng(5);
  for (const std::string method : {"", "cfl"}) {
    std::vector<DistanceRow> rows;
    std::string text = std::string(kDistanceCsvHeader) + (method.empty() ? "" : ",method") + "\n";
    for (long i = 0; i < 40; ++i) {
      rows.push_back(randomRow(rng, i, method.empty() ? "" : (i % 2 ? "obbrss" : "cfl")));
      text += formatDistanceRow(rows.back()) + "\n";
    }
    std::istringstream in(text);
    const auto read = readDistanceCsv(in, "out.csv");
    ASSERT_EQ(read.size(), rows.size());
    for (std::size_t i = 0; i < rows.size(); ++i) {
      EXPECT_EQ(read[i].pose, rows[i].pose);
      EXPECT_EQ(read[i].distance, rows[i].distance);
      EXPECT_EQ(read[i].point_a, rows[i].point_a);
      EXPECT_EQ(read[i].point_b, rows[i].point_b);
      EXPECT_EQ(read[i].triangle_a, rows[i].triangle_a);
      EXPECT_EQ(read[i].triangle_b, rows[i].triangle_b);
      EXPECT_DOUBLE_EQ(read[i].micros, rows[i].micros);
      EXPECT_EQ(read[i].method, rows[i].method);
    }
  }
}

std::string csvError(const std::string& text) {
  return messageOf<Error>([&] {
    std::istringstream in(text);
    readDistanceCsv(in, "out.csv");
  });
}

TEST(DistanceCsvTest, MalformedInputNamesTheLine) {
  const std::string header = std::string(kDistanceCsvHeader) + "\n";
  const std::string good = "0,1.5,0,0,0,1,1,1,3,4,12.5\n";
  EXPECT_NE(csvError("").find("out.csv:1:"), std::string::npos);
  EXPECT_NE(csvError("pose,distance\n").find("out.csv:1:"), std::string::npos);
  // Line numbers count the header as line 1.
  const std::string too_few = csvError(header + good + "1,1.5,0,0,0,1,1,1,3,4\n");
  EXPECT_NE(too_few.find("out.csv:3:"), std::string::npos) << too_few;
  EXPECT_NE(too_few.find("found 10"), std::string::npos) << too_few;
  const std::string not_number = csvError(header + good + good + "2,abc,0,0,0,1,1,1,3,4,1\n");
  EXPECT_NE(not_number.find("out.csv:4:"), std::string::npos) << not_number;
  EXPECT_NE(not_number.find("field 2"), std::string::npos) << not_number;
  EXPECT_NE(csvError(header + "0,1.5,0,0,0,1,1,1,3.5,4,1\n").find("not an integer"), std::string::npos);
  EXPECT_NE(csvError(header + "-1,1,0,0,0,1,1,1,3,4,1\n").find("out.csv:2:"), std::string::npos);
  EXPECT_NE(csvError(header + "0,1,0,0,0,1,1,1,3,4,-1\n").find("out.csv:2:"), std::string::npos);
  EXPECT_NE(csvError(header + "0,nan,0,0,0,1,1,1,3,4,1\n").find("out.csv:2:"), std::string::npos);
  const std::string bad_method = csvError(std::string(kDistanceCsvHeader) + ",method\n0,1,0,0,0,1,1,1,3,4,1,pqp\n");
  EXPECT_NE(bad_method.find("out.csv:2:"), std::string::npos) << bad_method;
  EXPECT_NE(bad_method.find("pqp"), std::string::npos) << bad_method;
}

TEST(ArgsTest, PositionalsOptionsAndFlagsAreSeparated) {
  const ParsedArgs a = parseArgs({"a.obj", "--queries", "10", "b.obj", "--bands=0,0.5", "-", "-1", "--json", "x.json"},
                                 {{"queries"}, {"bands"}, {"json"}, {"verbose", false}});
  EXPECT_EQ(a.positionals, (std::vector<std::string>{"a.obj", "b.obj", "-", "-1"}));
  EXPECT_EQ(a.get("queries"), "10");
  EXPECT_EQ(a.get("bands"), "0,0.5");
  EXPECT_EQ(a.get("json"), "x.json");
  EXPECT_FALSE(a.has("verbose"));
  EXPECT_FALSE(a.has("help"));
  EXPECT_TRUE(parseArgs({"-h"}, {}).has("help"));
  EXPECT_TRUE(parseArgs({"--help"}, {}).has("help"));
  // After "--" everything is positional.
  const ParsedArgs b = parseArgs({"--", "--queries"}, {{"queries"}});
  EXPECT_EQ(b.positionals, (std::vector<std::string>{"--queries"}));
  // A value that looks like an option is still the value.
  EXPECT_EQ(parseArgs({"--seed", "--x"}, {{"seed"}}).get("seed"), "--x");
}

TEST(ArgsTest, CommandLineMistakesNameTheOption) {
  const std::vector<OptionSpec> spec = {{"queries"}, {"verbose", false}};
  EXPECT_NE(messageOf<UsageError>([&] { parseArgs({"--bogus"}, spec); }).find("--bogus"), std::string::npos);
  EXPECT_NE(messageOf<UsageError>([&] { parseArgs({"--queries"}, spec); }).find("--queries"), std::string::npos);
  EXPECT_NE(messageOf<UsageError>([&] { parseArgs({"--verbose=1"}, spec); }).find("--verbose"), std::string::npos);
}

TEST(ArgsTest, NumbersMustBeWholeAndInRange) {
  EXPECT_EQ(parseInteger("42", "--n", 0, 100), 42);
  EXPECT_EQ(parseInteger("-3", "--n", -5, 5), -3);
  for (const std::string bad : {"", "4x", "x", "1.5", "101", "-1", "99999999999999999999"}) {
    const std::string message = messageOf<UsageError>([&] { parseInteger(bad, "--n", 0, 100); });
    EXPECT_NE(message.find("--n"), std::string::npos) << bad;
    EXPECT_NE(message.find("'" + bad + "'"), std::string::npos) << bad;
  }
  EXPECT_EQ(parseReal("0.25", "--band", 0, 1), 0.25);
  for (const std::string bad : {"", "nan", "inf", "2", "-0.1", "0.1.2"}) {
    EXPECT_NE(messageOf<UsageError>([&] { parseReal(bad, "--band", 0, 1); }).find("--band"), std::string::npos) << bad;
  }
}

TEST(ArgsTest, BandListsParseAndNameTheBadItem) {
  EXPECT_EQ(parseBandList("0,0.005,0.02,0.1,0.5", "--bands"), (std::vector<double>{0, 0.005, 0.02, 0.1, 0.5}));
  EXPECT_EQ(parseBandList("1e-3", "--bands"), (std::vector<double>{1e-3}));
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"", "item 1"}, {"0,,1", "item 2"}, {"0,1,", "item 3"}, {"0,-1", "item 2"}, {"a", "item 1"}, {"0,nan", "item 2"}};
  for (const auto& [text, item] : bad) {
    const std::string message = messageOf<UsageError>([&] { parseBandList(text, "--bands"); });
    EXPECT_NE(message.find(item), std::string::npos) << text << ": " << message;
    EXPECT_NE(message.find("--bands"), std::string::npos) << text << ": " << message;
  }
}

// The two timing orders take the same samples (every method on every pose, `repeats` times, after two
// untimed warm-up queries each) and differ only in sequence: interleaved finishes a pose before the next,
// blocked runs each method over all poses before the next method.
TEST(MeasureTest, OrdersTakeEverySampleInTheirOwnSequence) {
  constexpr std::size_t kPoses = 5;
  constexpr int kRepeats = 3;
  std::vector<std::pair<int, std::size_t>> calls;  // (method, pose)
  std::vector<IndexedMethod> methods;
  for (int j = 0; j < 3; ++j) {
    methods.push_back({"m" + std::to_string(j), [&calls, j](std::size_t i) {
                         calls.emplace_back(j, i);
                         return double(10 * j) + double(i);
                       }});
  }
  for (const Order order : {Order::kInterleaved, Order::kBlocked}) {
    calls.clear();
    const std::vector<MethodSamples> samples = timeIndexedMethods(kPoses, methods, kRepeats, Clock::kWall, order);
    ASSERT_EQ(samples.size(), methods.size());
    for (std::size_t j = 0; j < methods.size(); ++j) {
      ASSERT_EQ(samples[j].micros.size(), kPoses);
      for (std::size_t i = 0; i < kPoses; ++i) EXPECT_EQ(samples[j].distances[i], double(10 * j) + double(i));
    }
    const std::size_t warm_up = 2 * methods.size();
    ASSERT_EQ(calls.size(), warm_up + methods.size() * kPoses * kRepeats);
    const std::vector<std::pair<int, std::size_t>> timed(calls.begin() + std::ptrdiff_t(warm_up), calls.end());
    if (order == Order::kInterleaved) {
      // Pose i's samples are the block [i * 9, (i + 1) * 9): three of each method.
      for (std::size_t n = 0; n < timed.size(); ++n) EXPECT_EQ(timed[n].second, n / (methods.size() * kRepeats)) << n;
    } else {
      // Each run of kPoses samples is one method over poses 0..4, and every method runs once per repeat.
      for (int r = 0; r < kRepeats; ++r) {
        std::set<int> seen;
        for (std::size_t block = 0; block < methods.size(); ++block) {
          const std::size_t begin = (r * methods.size() + block) * kPoses;
          const int method = timed[begin].first;
          seen.insert(method);
          for (std::size_t i = 0; i < kPoses; ++i) {
            EXPECT_EQ(timed[begin + i], std::make_pair(method, i)) << "repeat " << r << " block " << block;
          }
        }
        EXPECT_EQ(seen.size(), methods.size()) << "repeat " << r;
      }
    }
  }
}

}  // namespace
}  // namespace cfl::tool
