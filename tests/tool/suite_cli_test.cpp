// `cfl suite` run as a user runs it: a tiny suite goes through to one table with a row per case, worst
// first, exact answers and positive heap figures; bad suites fail with status 1 naming the culprit; and
// `--generate` writes the shapes issue 31 asks for, which a few geometric checks confirm.

#include "cfl/mesh.h"
#include "cfl/mesh_io.h"
#include "support/test_meshes.h"

#include "tool_process.h"

#include <gtest/gtest.h>

#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace cfl {
namespace {

using tool_test::contains;
using tool_test::readFile;
using tool_test::ToolRun;
using tool_test::writeFile;

void writeObj(const std::string& path, const TriangleMesh& m) { writeFile(path, tool_test::objText(m)); }

std::vector<std::string> splitOn(const std::string& text, char separator) {
  std::vector<std::string> parts;
  std::stringstream s(text);
  for (std::string part; std::getline(s, part, separator);) parts.push_back(part);
  return parts;
}

std::vector<std::string> words(const std::string& text) {
  std::istringstream s(text);
  std::vector<std::string> w;
  for (std::string word; s >> word;) w.push_back(word);
  return w;
}

class SuiteCliTest : public tool_test::ToolTempDirTest {
 protected:
  SuiteCliTest() : ToolTempDirTest("cfl_suite_cli_") {}

  ToolRun run(const std::vector<std::string>& args) { return tool_test::runTool(dir_, args); }
};

// One table row, split into its '|'-separated columns; empty when the case has no row.
std::vector<std::string> rowOf(const std::string& out, const std::string& name) {
  for (const std::string& line : splitOn(out, '\n')) {
    const auto w = words(line);
    if (!w.empty() && w[0] == name) return splitOn(line, '|');
  }
  return {};
}

double ratioOf(const std::string& cell) {
  EXPECT_EQ(cell.back(), 'x') << cell;
  return std::stod(cell.substr(0, cell.size() - 1));
}

TEST_F(SuiteCliTest, TinySuitePrintsOneExactRowPerCaseWorstFirst) {
  const std::string suite = path("suite");
  ASSERT_EQ(::mkdir(suite.c_str(), 0755), 0);
  writeObj(suite + "/torus.obj", test::makeTorus(1.0, 0.3, 20, 10));
  writeObj(suite + "/box.obj", test::makeBox({-0.9, -0.9, -0.9}, {0.9, 0.9, 0.9}));
  writeFile(suite + "/manifest.txt",
            "# two cases\ntorus torus.obj\n\ntorus_vs_box torus.obj box.obj   # a pair\nbox box.obj\n");
  const ToolRun r = run({"suite", suite, "--queries", "3", "--bands", "0,0.02,0.5", "--repeats", "1", "--threads",
                         "1", "--clock", "cpu", "--seed", "5"});
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_TRUE(contains(r.out, "OBBRSS time / CFL time")) << r.out;
  EXPECT_TRUE(contains(r.out, "max|d|/diag")) << r.out;

  const std::map<std::string, std::string> triangles = {
      {"torus", "400"}, {"torus_vs_box", "400/12"}, {"box", "12"}};
  std::vector<std::pair<std::size_t, double>> order;  // (line position, 2% ratio)
  for (const auto& [name, tris] : triangles) {
    const std::vector<std::string> row = rowOf(r.out, name);
    ASSERT_EQ(row.size(), 5u) << name << "\n" << r.out;
    EXPECT_EQ(words(row[0]), (std::vector<std::string>{name, tris})) << row[0];
    const auto ratios = words(row[1]);
    ASSERT_EQ(ratios.size(), 3u) << row[1];
    for (const auto& cell : ratios) EXPECT_GT(ratioOf(cell), 0) << name;
    const auto heap = words(row[2]);
    ASSERT_EQ(heap.size(), 2u) << row[2];
    // Both models hold at least their own copy of the triangles' corners (3 doubles, 3 indices).
    EXPECT_GT(std::stod(heap[0]), 36) << name;
    EXPECT_GT(std::stod(heap[1]), 36) << name;
    const auto build = splitOn(words(row[3])[0], '/');
    ASSERT_EQ(build.size(), 2u) << row[3];
    EXPECT_GE(std::stod(build[0]), 0) << name;
    EXPECT_GE(std::stod(build[1]), 0) << name;
    const auto difference = words(row[4]);
    ASSERT_GE(difference.size(), 1u);
    EXPECT_LE(std::stod(difference[0]), 1e-9) << name;
    EXPECT_EQ(difference.size(), 1u) << "marked: " << row[4];
    order.push_back({r.out.find("\n" + name + " "), ratioOf(ratios[1])});
  }
  // The only short-range band is 2%, so rows must come in increasing order of its ratio.
  std::sort(order.begin(), order.end());
  for (std::size_t i = 1; i < order.size(); ++i) EXPECT_LE(order[i - 1].second, order[i].second) << r.out;
}

// bench/sweep_models.sh over a small tree as a user's model directory might be: each distinct mesh in the
// size range becomes one case (a copy of a mesh under another name does not, nor does one too small), and with
// PAIRS=1 one more against another mesh; a file cfl cannot read is listed with the reason, a directory whose
// name holds a space still works, and the suite runs to one exact row per case.
TEST_F(SuiteCliTest, SweepScriptRunsEveryDistinctReadableMeshOfATree) {
  const std::string models = path("models"), nested = models + "/two words";
  ASSERT_EQ(::mkdir(models.c_str(), 0755), 0);
  ASSERT_EQ(::mkdir(nested.c_str(), 0755), 0);
  writeObj(models + "/torus.obj", test::makeTorus(1.0, 0.3, 20, 10));
  writeObj(models + "/torus_copy.obj", test::makeTorus(1.0, 0.3, 20, 10));
  writeObj(nested + "/knot.obj", test::makeTorusKnot(2, 3, 1.0, 0.3, 40, 8));
  writeObj(models + "/box.obj", test::makeBox({-1, -1, -1}, {1, 1, 1}));
  writeFile(models + "/notes.txt", "not a mesh\n");
  const std::string out = path("sweep");
  const std::string command = "/usr/bin/env CFL=" + tool_test::quote(CFL_TOOL_PATH) + " MIN_TRIANGLES=100 PAIRS=1 bash " +
                              tool_test::quote(CFL_SWEEP_SCRIPT) + " " + tool_test::quote(models) + " " +
                              tool_test::quote(out) + " --queries 2 --repeats 1 --bands 0.02 --threads 1 > " +
                              tool_test::quote(path("stdout.txt")) + " 2> " + tool_test::quote(path("stderr.txt"));
  const int raw = std::system(command.c_str());
  const std::string stdout_text = readFile(path("stdout.txt")), stderr_text = readFile(path("stderr.txt"));
  ASSERT_TRUE(WIFEXITED(raw) && WEXITSTATUS(raw) == 0) << stdout_text << stderr_text;
  EXPECT_TRUE(contains(stdout_text, "2 meshes of 100 to 150000 triangles; 1 files repeat a mesh already kept, 1 lie "
                                    "outside that range, 1 are refused"))
      << stdout_text;
  const std::string refused = readFile(out + "/refused.txt");
  EXPECT_TRUE(contains(refused, models + "/notes.txt: ")) << refused;
  std::vector<std::string> names;
  for (const std::string& line : splitOn(readFile(out + "/manifest.txt"), '\n')) {
    if (!line.empty()) names.push_back(words(line).at(0));
  }
  const std::vector<std::string> expected = {"torus_obj", "two_words_knot_obj", "torus_obj_vs_two_words_knot_obj",
                                             "two_words_knot_obj_vs_torus_obj"};
  EXPECT_EQ(std::set<std::string>(names.begin(), names.end()), std::set<std::string>(expected.begin(), expected.end()));
  for (const std::string& name : names) {
    const std::vector<std::string> row = rowOf(stdout_text, name);
    ASSERT_EQ(row.size(), 5u) << name << "\n" << stdout_text;
    EXPECT_GT(ratioOf(words(row[1]).at(0)), 0) << name;
    EXPECT_LE(std::stod(words(row[4]).at(0)), 1e-9) << name;
    EXPECT_EQ(words(row[4]).size(), 1u) << "marked: " << row[4];
  }
  const std::vector<std::string> pair = rowOf(stdout_text, "torus_obj_vs_two_words_knot_obj");
  ASSERT_FALSE(pair.empty()) << stdout_text;
  EXPECT_EQ(words(pair[0]).at(1), "400/640") << pair[0];
}

TEST_F(SuiteCliTest, BadSuitesFailNamingTheCulprit) {
  const std::string suite = path("suite");
  {
    const ToolRun r = run({"suite", suite});
    EXPECT_EQ(r.status, 1);
    EXPECT_TRUE(contains(r.err, suite + ": no such suite directory")) << r.err;
  }
  ASSERT_EQ(::mkdir(suite.c_str(), 0755), 0);
  {
    const ToolRun r = run({"suite", suite});
    EXPECT_EQ(r.status, 1);
    EXPECT_TRUE(contains(r.err, "manifest.txt: missing")) << r.err;
  }
  writeObj(suite + "/box.obj", test::makeBox({0, 0, 0}, {1, 1, 1}));
  const std::vector<std::pair<std::string, std::string>> manifests = {
      {"box box.obj\nlonely\n", "manifest.txt:2: expected NAME MESH_A [MESH_B], found 1 word"},
      {"box box.obj\nbox box.obj\n", "manifest.txt:2: case 'box' appears twice"},
      {"# nothing\n", "manifest.txt: the manifest lists no case"},
      {"box box.obj\npair box.obj gone.obj\n", "case 'pair' (" + suite + "/manifest.txt:2): " + suite + "/gone.obj: no such mesh file"},
      {"broken broken.obj\n", suite + "/broken.obj"},
  };
  writeFile(suite + "/broken.obj", "v 0 0 0\nv 1 0 0\nf 1 2 7\n");
  for (const auto& [manifest, message] : manifests) {
    writeFile(suite + "/manifest.txt", manifest);
    const ToolRun r = run({"suite", suite, "--queries", "1"});
    EXPECT_EQ(r.status, 1) << manifest;
    EXPECT_TRUE(contains(r.err, message)) << manifest << "\n" << r.err;
    // Input errors stop the run before anything is measured.
    EXPECT_FALSE(contains(r.out, "OBBRSS time")) << r.out;
  }
  writeFile(suite + "/manifest.txt", "box box.obj\n");
  const ToolRun r = run({"suite", suite, "--cases", "nope"});
  EXPECT_EQ(r.status, 2);
  EXPECT_TRUE(contains(r.err, "no case 'nope'")) << r.err;
}

// Edges used by exactly one triangle, and the largest number of triangles on one edge.
std::pair<int, int> edgeUse(const TriangleMesh& m) {
  std::map<std::pair<int, int>, int> uses;
  for (const auto& t : m.triangles) {
    for (int k = 0; k < 3; ++k) ++uses[{std::min(t[k], t[(k + 1) % 3]), std::max(t[k], t[(k + 1) % 3])}];
  }
  int boundary = 0, most = 0;
  for (const auto& [edge, n] : uses) {
    boundary += n == 1;
    most = std::max(most, n);
  }
  return {boundary, most};
}

TEST_F(SuiteCliTest, GenerateWritesTheShapesIssue31AsksFor) {
  const std::string suite = path("generated");
  const ToolRun r = run({"suite", "--generate", suite});
  ASSERT_EQ(r.status, 0) << r.err;

  std::set<std::string> meshes, names;
  int pairs = 0;
  for (const std::string& line : splitOn(readFile(suite + "/manifest.txt"), '\n')) {
    const auto w = words(line.substr(0, line.find('#')));
    if (w.empty()) continue;
    ASSERT_GE(w.size(), 2u) << line;
    ASSERT_LE(w.size(), 3u) << line;
    names.insert(w[0]);
    for (std::size_t i = 1; i < w.size(); ++i) {
      meshes.insert(w[i]);
      // Real meshes are listed by absolute path, read in place (see generateSuite).
      const std::string file = w[i].front() == '/' ? w[i] : suite + "/" + w[i];
      EXPECT_EQ(::access(file.c_str(), R_OK), 0) << w[i];
    }
    pairs += w.size() == 3 && w[1] != w[2];
  }
  EXPECT_GE(meshes.size(), 12u);
  EXPECT_GE(pairs, 3);

  const TriangleMesh blade = loadMesh(suite + "/blade.obj");
  const Aabb box = boundingBox(blade);
  const Eigen::Vector3d extent = box.max - box.min;
  EXPECT_GT(extent.maxCoeff() / extent.minCoeff(), 100) << "a long flat part";
  EXPECT_GE(blade.triangles.size(), 15000u);

  const TriangleMesh soup = loadMesh(suite + "/soup_rock.stl");
  EXPECT_EQ(soup.vertices.size(), 3 * soup.triangles.size()) << "a soup shares no vertex, even after loading";

  EXPECT_GT(edgeUse(loadMesh(suite + "/open_bowl.obj")).first, 0) << "an open mesh has boundary edges";
  EXPECT_GT(edgeUse(loadMesh(suite + "/nonmanifold_fins.obj")).second, 2) << "non-manifold edges";
  const auto closed = edgeUse(loadMesh(suite + "/plate_holes.obj"));
  EXPECT_EQ(closed.first, 0);
  EXPECT_EQ(closed.second, 2) << "the plate is a closed manifold";

  const TriangleMesh assembly = loadMesh(suite + "/assembly.obj"), bolt = loadMesh(suite + "/bolt.obj");
  EXPECT_GE(boundingBox(assembly).diagonal() / boundingBox(bolt).diagonal(), 50) << "parts far apart in size";
  EXPECT_GE(loadMesh(suite + "/dense_scan.obj").triangles.size(), 350000u);
  EXPECT_FALSE(names.count("dense_scan_huge")) << "the 1.4M case is only written with --huge";

  // The CAD-export family: planar faces fanned from one vertex. Counts follow from the stated resolutions
  // (quads of the sides, plus one sliver per rim point of each fan cap).
  struct Expected {
    std::string mesh;
    std::size_t triangles;
    int boundary_edges;  // 0: a closed manifold, which `cfl info` must also report closed
  };
  const std::vector<Expected> cad = {
      {"fan_disk.obj", 3000, 3000},                      // the rim of a 3000-sliver fan
      {"cad_cylinder.obj", 2 * 256 * 20 + 2 * 256, 0},   // 21 rings of 256
      {"pipe.obj", 2 * 16 * 399 + 2 * 16, 0},            // 400 rings of 16
      {"gear.obj", 2 * 300 + 2 * 300, 0},                // 60 teeth of 5 profile points, one band
      {"terrain.obj", 2 * 149 * 149, 4 * 149},           // 150 x 150 vertices
  };
  for (const Expected& e : cad) {
    EXPECT_TRUE(meshes.count(e.mesh)) << e.mesh << " is in the manifest";
    const TriangleMesh m = loadMesh(suite + "/" + e.mesh);
    EXPECT_EQ(m.triangles.size(), e.triangles) << e.mesh;
    const auto [boundary, most] = edgeUse(m);
    EXPECT_EQ(boundary, e.boundary_edges) << e.mesh;
    EXPECT_EQ(most, 2) << e.mesh << " is manifold";
    for (const auto& t : m.triangles) {
      const Eigen::Vector3d n = (m.vertices[t[1]] - m.vertices[t[0]]).cross(m.vertices[t[2]] - m.vertices[t[0]]);
      ASSERT_GT(n.norm(), 0) << e.mesh << ": a degenerate triangle";
    }
    if (e.mesh != "terrain.obj") {  // building the terrain's model is slow; its edges are checked above
      const ToolRun info = run({"info", suite + "/" + e.mesh});
      ASSERT_EQ(info.status, 0) << info.err;
      EXPECT_TRUE(contains(info.out, e.boundary_edges == 0 ? "closed:              yes" : "closed:              no (open"))
          << e.mesh << "\n" << info.out;
    }
  }
  // A fan: one vertex shared by all 3000 triangles of the disk.
  const TriangleMesh disk = loadMesh(suite + "/fan_disk.obj");
  std::map<int, int> degree;
  for (const auto& t : disk.triangles) {
    for (int v : t) ++degree[v];
  }
  int most_used = 0;
  for (const auto& [v, n] : degree) most_used = std::max(most_used, n);
  EXPECT_EQ(most_used, 3000);
  for (const char* pair : {"fan_disk_vs_bunny", "cad_cylinder_vs_gear", "pipe_vs_gear"}) {
    EXPECT_TRUE(names.count(pair)) << pair;
  }
}

}  // namespace
}  // namespace cfl
