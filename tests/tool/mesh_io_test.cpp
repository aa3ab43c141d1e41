// cfl::loadMesh: every format the tool advertises round-trips the triangles in order (ids preserved, also
// for degenerate triangles), scenes are flattened with their node transforms, and every bad file is refused
// with a message naming it.

#include "cfl/error.h"
#include "cfl/mesh_io.h"
#include "support/test_meshes.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <random>
#include <string>
#include <unistd.h>

namespace cfl {
namespace {

// assimp stores coordinates as floats, so meshes are rounded to float before writing; the round trip is
// then exact and the tests can compare positions with ==.
TriangleMesh roundToFloat(TriangleMesh mesh) {
  for (auto& v : mesh.vertices) v = v.cast<float>().cast<double>();
  return mesh;
}

void writeText(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  ASSERT_TRUE(out.good()) << path;
}

std::string num(double v) {
  char buffer[40];
  std::snprintf(buffer, sizeof buffer, "%.9g", v);  // 9 digits: exact for floats
  return buffer;
}

std::string objText(const TriangleMesh& m) {
  std::string s = "# written by mesh_io_test\n";
  for (const auto& v : m.vertices) s += "v " + num(v.x()) + " " + num(v.y()) + " " + num(v.z()) + "\n";
  for (const auto& t : m.triangles) {
    s += "f " + std::to_string(t[0] + 1) + " " + std::to_string(t[1] + 1) + " " + std::to_string(t[2] + 1) + "\n";
  }
  return s;
}

std::string offText(const TriangleMesh& m) {
  std::string s = "OFF\n" + std::to_string(m.vertices.size()) + " " + std::to_string(m.triangles.size()) + " 0\n";
  for (const auto& v : m.vertices) s += num(v.x()) + " " + num(v.y()) + " " + num(v.z()) + "\n";
  for (const auto& t : m.triangles) {
    s += "3 " + std::to_string(t[0]) + " " + std::to_string(t[1]) + " " + std::to_string(t[2]) + "\n";
  }
  return s;
}

std::string plyText(const TriangleMesh& m) {
  std::string s = "ply\nformat ascii 1.0\nelement vertex " + std::to_string(m.vertices.size()) +
                  "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
                  std::to_string(m.triangles.size()) + "\nproperty list uchar int vertex_indices\nend_header\n";
  for (const auto& v : m.vertices) s += num(v.x()) + " " + num(v.y()) + " " + num(v.z()) + "\n";
  for (const auto& t : m.triangles) {
    s += "3 " + std::to_string(t[0]) + " " + std::to_string(t[1]) + " " + std::to_string(t[2]) + "\n";
  }
  return s;
}

std::string stlAsciiText(const TriangleMesh& m) {
  std::string s = "solid test\n";
  for (const auto& t : m.triangles) {
    s += " facet normal 0 0 0\n  outer loop\n";
    for (int c = 0; c < 3; ++c) {
      const auto& v = m.vertices[std::size_t(t[c])];
      s += "   vertex " + num(v.x()) + " " + num(v.y()) + " " + num(v.z()) + "\n";
    }
    s += "  endloop\n endfacet\n";
  }
  return s + "endsolid test\n";
}

std::string stlBinary(const TriangleMesh& m) {
  std::string s(80, ' ');
  auto put32 = [&](std::uint32_t v) {
    for (int i = 0; i < 4; ++i) s += char((v >> (8 * i)) & 0xFF);
  };
  auto putFloat = [&](float f) {
    std::uint32_t bits;
    std::memcpy(&bits, &f, 4);
    put32(bits);
  };
  put32(std::uint32_t(m.triangles.size()));
  for (const auto& t : m.triangles) {
    for (int i = 0; i < 3; ++i) putFloat(0.0f);
    for (int c = 0; c < 3; ++c) {
      const auto& v = m.vertices[std::size_t(t[c])];
      for (int i = 0; i < 3; ++i) putFloat(float(v[i]));
    }
    s += std::string(2, '\0');
  }
  return s;
}

// Coordinates agree to 2 float ulps: assimp's text number parser is not always correctly rounded.
bool sameFloatPosition(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return ((a - b).array().abs() <= 2.5e-7 * b.array().abs()).all();
}

// Triangle t of `loaded` has the corners of triangle t of `expected`, in the same order.
void expectSameTrianglesInOrder(const TriangleMesh& expected, const TriangleMesh& loaded, const std::string& what) {
  ASSERT_EQ(loaded.triangles.size(), expected.triangles.size()) << what;
  for (std::size_t t = 0; t < expected.triangles.size(); ++t) {
    for (int c = 0; c < 3; ++c) {
      const Eigen::Vector3d& e = expected.vertices[std::size_t(expected.triangles[t][c])];
      const Eigen::Vector3d& l = loaded.vertices[std::size_t(loaded.triangles[t][c])];
      ASSERT_TRUE(sameFloatPosition(l, e)) << what << ": corner " << c << " of triangle " << t << " is ("
                                           << l.transpose() << "), expected (" << e.transpose() << ")";
    }
  }
  EXPECT_NO_THROW(validateMesh(loaded)) << what;
}

// Every refusal is a cfl::Error whose message starts with the path and contains the reason.
void expectErrorNaming(const std::string& file, const std::string& reason) {
  try {
    loadMesh(file);
    FAIL() << "loading " << file << " did not throw";
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind(file, 0), 0u) << message;
    EXPECT_NE(message.find(reason), std::string::npos) << message;
  }
}

class MeshIoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = ::testing::TempDir() + "cfl_mesh_io_XXXXXX";
    ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
    dir_ = pattern;
  }
  void TearDown() override { std::system(("rm -rf '" + dir_ + "'").c_str()); }
  std::string path(const std::string& name) const { return dir_ + "/" + name; }

  // Writes `mesh` in every text and binary format and checks each loads back triangle for triangle.
  void expectRoundTripInEveryFormat(const TriangleMesh& source, const std::string& label) {
    const TriangleMesh mesh = roundToFloat(source);
    const std::vector<std::pair<std::string, std::string>> files = {
        {label + ".obj", objText(mesh)}, {label + ".off", offText(mesh)},        {label + ".ply", plyText(mesh)},
        {label + ".stl", stlAsciiText(mesh)}, {label + "_binary.stl", stlBinary(mesh)},
    };
    for (const auto& [name, content] : files) {
      writeText(path(name), content);
      TriangleMesh loaded;
      ASSERT_NO_THROW(loaded = loadMesh(path(name))) << name;
      expectSameTrianglesInOrder(mesh, loaded, name);
    }
  }

  // Writes each (file text, expected reason) case to its own file with `extension` and expects loadMesh to
  // refuse it naming the file and the reason.
  void expectEachRefused(const std::vector<std::pair<std::string, std::string>>& cases, const std::string& extension) {
    int n = 0;
    for (const auto& [text, reason] : cases) {
      const std::string file = path("bad" + std::to_string(n++) + extension);
      writeText(file, text);
      expectErrorNaming(file, reason);
    }
  }

  std::string dir_;
};


TEST_F(MeshIoTest, EveryFormatRoundTripsTrianglesInFileOrder) {
  expectRoundTripInEveryFormat(test::makeTorus(1.0, 0.35, 12, 8), "torus");
  expectRoundTripInEveryFormat(test::makeTriangleSoup(60, 7), "soup");
}

TEST_F(MeshIoTest, DegenerateAndDuplicateTrianglesKeepTheirIds) {
  // Zero-area, collinear, duplicated and non-manifold triangles: dropping any of them would shift the ids of
  // every later triangle.
  const TriangleMesh messy = test::makeMessyMesh();
  expectRoundTripInEveryFormat(messy, "messy");
}

TEST_F(MeshIoTest, BundledBunnyLoadsWithItsTriangleCount) {
  const TriangleMesh independent = test::loadBunny();  // the test support's own OBJ reader
  const TriangleMesh loaded = loadMesh(std::string(CFL_DATA_DIR) + "/bunny.obj");
  expectSameTrianglesInOrder(independent, loaded, "bunny.obj");
  // OBJ is read natively, in double: every corner is the support reader's to the bit.
  for (std::size_t t = 0; t < loaded.triangles.size(); ++t) {
    for (int c = 0; c < 3; ++c) {
      ASSERT_EQ(loaded.vertices[std::size_t(loaded.triangles[t][c])],
                independent.vertices[std::size_t(independent.triangles[t][c])])
          << "corner " << c << " of triangle " << t;
    }
  }
}

TEST_F(MeshIoTest, ObjAndAsciiStlCoordinatesKeepEveryBitOfTheirDoubles) {
  // Coordinates a float cannot hold (a part 1000 units from the origin with micrometre detail, a mesh of
  // 1e-7 units), written with 17 significant digits: the distances are exact only if these survive.
  test::Rng rng(11);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  TriangleMesh mesh;
  for (const double scale : {1e-7, 1.0, 1e3, 1e15}) {
    for (int t = 0; t < 20; ++t) {
      const int first = int(mesh.vertices.size());
      for (int c = 0; c < 3; ++c) {
        mesh.vertices.emplace_back(scale * (1 + 1e-3 * unit(rng)), scale * unit(rng), -scale * unit(rng));
      }
      mesh.triangles.push_back({first, first + 1, first + 2});
    }
  }
  char buffer[100];
  auto coordinates = [&](const Eigen::Vector3d& v) {
    std::snprintf(buffer, sizeof buffer, "%.17g %.17g %.17g", v.x(), v.y(), v.z());
    return std::string(buffer);
  };
  std::string obj, stl = "solid precise\n";
  for (const auto& v : mesh.vertices) obj += "v " + coordinates(v) + "\n";
  for (const auto& t : mesh.triangles) {
    obj += "f " + std::to_string(t[0] + 1) + " " + std::to_string(t[1] + 1) + " " + std::to_string(t[2] + 1) + "\n";
    stl += "facet normal 0 0 1\nouter loop\n";
    for (int c = 0; c < 3; ++c) stl += "vertex " + coordinates(mesh.vertices[std::size_t(t[c])]) + "\n";
    stl += "endloop\nendfacet\n";
  }
  stl += "endsolid precise\n";
  writeText(path("precise.obj"), obj);
  writeText(path("precise.stl"), stl);
  for (const char* name : {"precise.obj", "precise.stl"}) {
    const TriangleMesh loaded = loadMesh(path(name));
    ASSERT_EQ(loaded.triangles.size(), mesh.triangles.size()) << name;
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
      for (int c = 0; c < 3; ++c) {
        ASSERT_EQ(loaded.vertices[std::size_t(loaded.triangles[t][c])], mesh.vertices[std::size_t(mesh.triangles[t][c])])
            << name << ": corner " << c << " of triangle " << t;
      }
    }
  }
}

TEST_F(MeshIoTest, AsciiStlKeywordsSolidsAndPolygonLoopsAreRead) {
  // Upper-case keywords, two solids, a loop of four vertices (two triangles), and a binary file whose
  // 80-byte header starts with "solid", which is still binary by its size.
  writeText(path("two.stl"),
            "SOLID first\n  FACET NORMAL 0 0 1\n    OUTER LOOP\n      VERTEX 0 0 0\n      VERTEX 1 0 0\n"
            "      VERTEX 0 1 0\n    ENDLOOP\n  ENDFACET\nENDSOLID first\n\n"
            "solid second\nfacet normal 0 0 1\nouter loop\nvertex 0 0 5\nvertex 2 0 5\nvertex 2 1 5\nvertex 0 1 5\n"
            "endloop\nendfacet\nendsolid second\n");
  const TriangleMesh m = loadMesh(path("two.stl"));
  ASSERT_EQ(m.triangles.size(), 3u);
  for (int c = 0; c < 3; ++c) EXPECT_EQ(m.vertices[std::size_t(m.triangles[0][c])].z(), 0.0);
  for (std::size_t t : {1u, 2u}) {
    for (int c = 0; c < 3; ++c) EXPECT_EQ(m.vertices[std::size_t(m.triangles[t][c])].z(), 5.0);
  }
  const TriangleMesh torus = roundToFloat(test::makeTorus(1.0, 0.35, 12, 8));
  std::string binary = stlBinary(torus);
  binary.replace(0, 11, "solid torus");
  writeText(path("solid_header.stl"), binary);
  expectSameTrianglesInOrder(torus, loadMesh(path("solid_header.stl")), "solid_header.stl");
}

TEST_F(MeshIoTest, AsciiStlErrorsNameTheLine) {
  const std::string head = "solid s\nfacet normal 0 0 1\nouter loop\n";  // lines 1-3
  const std::vector<std::pair<std::string, std::string>> cases = {
      {head + "vertex 0 0 0\nvertex 1 y 0\n", "line 5: coordinate 'y' is not a number"},
      {head + "vertex 0 0\n", "line 4: a vertex has 2 coordinates, needs 3"},
      {head + "vertex 0 0 0\nvertex 1 0 0\nendloop\n", "line 6: a facet's loop has 2 vertices, needs 3"},
      {"solid s\nvertex 0 0 0\n", "line 2: a vertex outside an 'outer loop'"},
      {head + "vertex 0 0 0\nbanana\n", "line 5: 'banana' is not an ASCII STL statement"},
      {head + "vertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n", "ends inside a facet's loop"},
      {head + "vertex 0 0 inf\n", "line 4: coordinate 'inf' is not finite"},
  };
  expectEachRefused(cases, ".stl");
}

TEST_F(MeshIoTest, ObjFaceFormsCommentsAndContinuationsAreRead) {
  // Every corner form (v, v/t, v//n, v/t/n, negative), a comment after data, a continued line, CRLF line
  // ends, a face before the vertices it names, and faces split by objects, groups and materials, which
  // keep their file order (assimp would have regrouped them by material).
  writeText(path("forms.obj"),
            "# header\r\nmtllib none.mtl\r\no first\r\nv 0 0 0\r\nv 1 0 0 # trailing comment\r\nv 0 1 0\r\n"
            "vt 0 0\nvn 0 0 1\nusemtl red\nf 1/1 2/1/1 3//1\n"
            "g second\nusemtl blue\nf -3 -2 \\\n  -1\n"
            "usemtl red\ns off\nf 4 5 6\nv 0 0 7\nv 1 0 7\nv 0 1 7 1.0\np 1\nl 1 2\n");
  const TriangleMesh m = loadMesh(path("forms.obj"));
  ASSERT_EQ(m.triangles.size(), 3u);
  EXPECT_EQ(m.triangles[0], m.triangles[1]);  // the same corners named two ways
  EXPECT_EQ(m.vertices.size(), 6u);
  for (int c = 0; c < 3; ++c) EXPECT_EQ(m.vertices[std::size_t(m.triangles[2][c])].z(), 7.0);
  EXPECT_EQ(m.vertices[std::size_t(m.triangles[0][1])], Eigen::Vector3d(1, 0, 0));
}

TEST_F(MeshIoTest, ObjErrorsNameTheLine) {
  const std::string head = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";  // lines 1-3
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"v 0 0 0\nv 1 x 0\n", "line 2: coordinate 'x' is not a number"},
      {"v 0 0 0\nv 1 0\n", "line 2: vertex 2 has 2 coordinates, needs 3"},
      {"v 0 0 0\nv 1 0 nan\n", "line 2: coordinate 'nan' is not finite"},
      {"v 0 0 0\nv 1 0 1e999\n", "line 2: coordinate '1e999' is beyond the double range"},
      {head + "f 1 2 0\n", "line 4: face corner '0' has vertex index 0"},
      {head + "f 1 2 -4\n", "line 4: face corner '-4' counts back further than the 3 vertices defined before it"},
      {head + "f 1 2 -9223372036854775808\n", "line 4: face corner '-9223372036854775808' counts back further"},
      {head + "f 1 2 99999999999999999999\n", "line 4: face corner '99999999999999999999' has a vertex index beyond any"},
      {head + "f 1 2\n", "line 4: a face needs at least 3 corners, this one has 2"},
      {head + "f 1 2 a\n", "line 4: face corner 'a' does not start with a vertex index"},
      {head + "# c\nf 1 2 3\nf 1 \\\n 2 7\nf 1 2 3\n", "line 6: a face refers to vertex 7, but the file defines 3"},
  };
  expectEachRefused(cases, ".obj");
}

TEST_F(MeshIoTest, PolygonsBecomeConsecutiveTrianglesCoveringThem) {
  // A triangle, a convex quad, a convex pentagon, a triangle: 1 + 2 + 3 + 1 triangles, in that order.
  writeText(path("polygons.obj"),
            "v 0 0 0\nv 1 0 0\nv 0 1 0\n"                             // 1-3 triangle
            "v 0 0 2\nv 2 0 2\nv 2 1 2\nv 0 1 2\n"                  // 4-7 quad in z = 2, area 2
            "v 0 0 5\nv 2 0 5\nv 3 1 5\nv 1 2 5\nv -1 1 5\n"          // 8-12 pentagon in z = 5
            "v 0 0 9\nv 0 1 9\nv 1 0 9\n"                             // 13-15 triangle
            "f 1 2 3\nf 4 5 6 7\nf 8 9 10 11 12\nf 13 14 15\n");
  const TriangleMesh m = loadMesh(path("polygons.obj"));
  ASSERT_EQ(m.triangles.size(), 7u);
  auto area = [&](std::size_t t) {
    const auto& v = m.vertices;
    const auto& tri = m.triangles[t];
    return 0.5 * (v[std::size_t(tri[1])] - v[std::size_t(tri[0])]).cross(v[std::size_t(tri[2])] - v[std::size_t(tri[0])]).norm();
  };
  auto allAtHeight = [&](std::size_t t, double z) {
    for (int c = 0; c < 3; ++c) {
      if (m.vertices[std::size_t(m.triangles[t][c])].z() != z) return false;
    }
    return true;
  };
  EXPECT_TRUE(allAtHeight(0, 0));
  EXPECT_TRUE(allAtHeight(1, 2) && allAtHeight(2, 2));
  EXPECT_NEAR(area(1) + area(2), 2.0, 1e-12);
  EXPECT_TRUE(allAtHeight(3, 5) && allAtHeight(4, 5) && allAtHeight(5, 5));
  // Shoelace area of the pentagon (0,0) (2,0) (3,1) (1,2) (-1,1): 5.
  EXPECT_NEAR(area(3) + area(4) + area(5), 5.0, 1e-12);
  EXPECT_TRUE(allAtHeight(6, 9));
}

TEST_F(MeshIoTest, ConcavePolygonsAreTriangulatedInsideWithTheirOrientation) {
  // An L-shaped hexagon of area 3 in z = 0, counter-clockwise seen from +z, starting at a corner from which
  // a fan would leave the polygon (the fan's first triangle would be clockwise).
  writeText(path("concave.obj"),
            "v 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nv 0 0 0\nv 2 0 0\nf 1 2 3 4 5 6\n");
  const TriangleMesh m = loadMesh(path("concave.obj"));
  ASSERT_EQ(m.triangles.size(), 4u);
  double total = 0;
  for (const auto& t : m.triangles) {
    const Eigen::Vector3d n = (m.vertices[std::size_t(t[1])] - m.vertices[std::size_t(t[0])])
                                  .cross(m.vertices[std::size_t(t[2])] - m.vertices[std::size_t(t[0])]);
    EXPECT_GT(n.z(), 0) << "a triangle is flipped or outside the polygon";
    total += 0.5 * n.norm();
  }
  EXPECT_NEAR(total, 3.0, 1e-12);
}

TEST_F(MeshIoTest, SceneNodesAreFlattenedWithTheirTransforms) {
  // One triangle instanced by a node translated by (10, 0, 0) and by its child, rotated 90 degrees about z
  // and translated by (0, 5, 0) relative to it.
  writeText(path("scene.dae"), R"(<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="meter" meter="1"/><up_axis>Y_UP</up_axis></asset>
  <library_geometries>
    <geometry id="tri" name="tri">
      <mesh>
        <source id="tri-pos">
          <float_array id="tri-pos-array" count="9">0 0 0 1 0 0 0 1 0</float_array>
          <technique_common>
            <accessor source="#tri-pos-array" count="3" stride="3">
              <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
            </accessor>
          </technique_common>
        </source>
        <vertices id="tri-vtx"><input semantic="POSITION" source="#tri-pos"/></vertices>
        <triangles count="1"><input semantic="VERTEX" source="#tri-vtx" offset="0"/><p>0 1 2</p></triangles>
      </mesh>
    </geometry>
  </library_geometries>
  <library_visual_scenes>
    <visual_scene id="scene">
      <node id="parent" name="parent">
        <matrix>1 0 0 10 0 1 0 0 0 0 1 0 0 0 0 1</matrix>
        <instance_geometry url="#tri"/>
        <node id="child" name="child">
          <matrix>0 -1 0 0 1 0 0 5 0 0 1 0 0 0 0 1</matrix>
          <instance_geometry url="#tri"/>
        </node>
      </node>
    </visual_scene>
  </library_visual_scenes>
  <scene><instance_visual_scene url="#scene"/></scene>
</COLLADA>
)");
  const TriangleMesh m = loadMesh(path("scene.dae"));
  TriangleMesh expected;
  expected.vertices = {{10, 0, 0}, {11, 0, 0}, {10, 1, 0}, {10, 5, 0}, {10, 6, 0}, {9, 5, 0}};
  expected.triangles = {{0, 1, 2}, {3, 4, 5}};
  expectSameTrianglesInOrder(expected, m, "scene.dae");
}

TEST_F(MeshIoTest, SharedPositionsAreMergedIntoOneVertex) {
  // Binary STL stores three private corners per facet; a closed torus has every corner shared.
  const TriangleMesh torus = roundToFloat(test::makeTorus(1.0, 0.35, 12, 8));
  writeText(path("torus.stl"), stlBinary(torus));
  const TriangleMesh m = loadMesh(path("torus.stl"));
  EXPECT_EQ(m.vertices.size(), torus.vertices.size());
}

TEST_F(MeshIoTest, MissingFileIsRefusedByName) { expectErrorNaming(path("nope.obj"), "No such file"); }

TEST_F(MeshIoTest, DirectoryIsRefusedByName) { expectErrorNaming(dir_, "directory"); }

TEST_F(MeshIoTest, EmptyFileIsRefusedByName) {
  writeText(path("empty.stl"), "");
  expectErrorNaming(path("empty.stl"), "empty");
}

TEST_F(MeshIoTest, GarbageIsRefusedByName) {
  std::string bytes;
  test::Rng rng(3);
  for (int i = 0; i < 500; ++i) bytes += char(rng() & 0xFF);
  for (const char* name : {"garbage.stl", "garbage.ply", "garbage.off", "garbage.obj", "garbage.xyz"}) {
    writeText(path(name), bytes);
    expectErrorNaming(path(name), "");
  }
}

TEST_F(MeshIoTest, FilesWithoutTrianglesAreRefusedByName) {
  writeText(path("points.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
  expectErrorNaming(path("points.obj"), "no triangle");
  writeText(path("lines.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2\nl 2 3\n");
  expectErrorNaming(path("lines.obj"), "no triangle");
  writeText(path("nofaces.off"), "OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n");
  expectErrorNaming(path("nofaces.off"), "");
}

TEST_F(MeshIoTest, TruncatedPlyIsRefusedByName) {
  const TriangleMesh torus = roundToFloat(test::makeTorus(1.0, 0.35, 12, 8));
  const std::string text = plyText(torus);
  writeText(path("truncated.ply"), text.substr(0, text.size() / 2));
  expectErrorNaming(path("truncated.ply"), "");
}

TEST_F(MeshIoTest, IncompleteSceneGraphIsRefusedByName) {
  // Two named objects in assimp's RAW format (a color, then a triangle's corners, per line): assimp 5.2
  // links only one of them into the scene graph and leaves a null child where the other should be.
  writeText(path("two_objects.raw"),
            "first\n0.2 0.2 0.2 0 0 0 0 1 0 1 0 0\n\nsecond\n0.2 0.2 0.2 0 0 3 0 1 3 1 0 3\n");
  try {
    const TriangleMesh mesh = loadMesh(path("two_objects.raw"));
    // An assimp that links both objects gives both triangles.
    EXPECT_EQ(mesh.triangles.size(), 2u);
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind(path("two_objects.raw"), 0), 0u) << message;
    EXPECT_NE(message.find("is missing"), std::string::npos) << message;
  }
}

TEST_F(MeshIoTest, OffCountsTheFileCannotHoldAreRefusedByName) {
  // A damaged vertex count that assimp would allocate for (gigabytes, minutes) before failing.
  writeText(path("huge.off"), "OFF\n3535352353586 0\n0 0 0\n1 0 0\n0 1 0\n");
  expectErrorNaming(path("huge.off"), "declares 3535352353586 vertices");
  // A face count larger than the file holds, which assimp would read as the faces present without a word.
  writeText(path("truncated.off"), "# a comment\nOFF\n3 1000 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  expectErrorNaming(path("truncated.off"), "1000 faces");
  // Counts the file can hold still load.
  writeText(path("one.off"), "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  EXPECT_EQ(loadMesh(path("one.off")).triangles.size(), 1u);
}

TEST_F(MeshIoTest, OutOfRangeFaceIndexIsRefusedByName) {
  // (Not OFF: assimp's OFF reader clamps such an index to the last vertex, and says so only in its log.)
  writeText(path("bad_index.ply"),
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 9\n");
  expectErrorNaming(path("bad_index.ply"), "vertex 9");
  writeText(path("bad_index.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
  expectErrorNaming(path("bad_index.obj"), "out of range");
}

}  // namespace
}  // namespace cfl
