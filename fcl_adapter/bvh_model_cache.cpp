// The per-BVHModel cache of cfl::MeshModel copies used when a CFLGeometry meets an fcl::BVHModel.
// Building a MeshModel is O(n log n); a query should not pay it, so copies are kept and validated in O(1).
#include "adapter_internal.h"

#include "cfl_fcl/cfl_geometry.h"

#include <cfl/error.h>

#include <fcl/math/bv/AABB.h>
#include <fcl/math/bv/OBB.h>
#include <fcl/math/bv/OBBRSS.h>
#include <fcl/math/bv/RSS.h>
#include <fcl/math/bv/kDOP.h>
#include <fcl/math/bv/kIOS.h>

#include <algorithm>
#include <array>
#include <climits>
#include <cstdint>
#include <mutex>
#include <string>
#include <unordered_map>

namespace cfl_fcl {
namespace detail {
namespace {

using Geometry = fcl::CollisionGeometry<double>;

constexpr int kSampledVertices = 64;
// More entries than this are trimmed (dead owners first, then least recently used): a program that keeps
// creating BVHModels must not grow the cache without bound.
constexpr std::size_t kMaxEntries = 256;

// What a BVHModel looks like now, to compare with what it looked like when its copy was made.
struct Fingerprint {
  const void* vertices = nullptr;
  const void* triangles = nullptr;
  int num_vertices = 0;
  int num_triangles = 0;
  int build_state = 0;
  std::array<fcl::Vector3d, kSampledVertices> samples;

  bool operator==(const Fingerprint& o) const {
    if (vertices != o.vertices || triangles != o.triangles || num_vertices != o.num_vertices ||
        num_triangles != o.num_triangles || build_state != o.build_state)
      return false;
    for (int i = 0; i < kSampledVertices; ++i)
      if (samples[i] != o.samples[i]) return false;
    return true;
  }
};

// The triangles of a BVHModel, whatever its BV type.
struct MeshView {
  const fcl::Vector3d* vertices = nullptr;
  const fcl::Triangle* triangles = nullptr;
  int num_vertices = 0;
  int num_triangles = 0;
  int build_state = 0;
};

template <typename BV>
bool viewAs(const Geometry* geometry, MeshView* view) {
  // dynamic_cast, not FCL's static_cast: a foreign geometry claiming a BV node type must not be misread.
  const auto* model = dynamic_cast<const fcl::BVHModel<BV>*>(geometry);
  if (model == nullptr) return false;
  view->vertices = model->vertices;
  view->triangles = model->tri_indices;
  view->num_vertices = model->num_vertices;
  view->num_triangles = model->num_tris;
  view->build_state = model->build_state;
  return true;
}

bool viewOf(const Geometry* geometry, MeshView* view) {
  if (geometry->getObjectType() != fcl::OT_BVH) return false;
  switch (geometry->getNodeType()) {
    case fcl::BV_AABB: return viewAs<fcl::AABB<double>>(geometry, view);
    case fcl::BV_OBB: return viewAs<fcl::OBB<double>>(geometry, view);
    case fcl::BV_RSS: return viewAs<fcl::RSS<double>>(geometry, view);
    case fcl::BV_kIOS: return viewAs<fcl::kIOS<double>>(geometry, view);
    case fcl::BV_OBBRSS: return viewAs<fcl::OBBRSS<double>>(geometry, view);
    case fcl::BV_KDOP16: return viewAs<fcl::KDOP<double, 16>>(geometry, view);
    case fcl::BV_KDOP18: return viewAs<fcl::KDOP<double, 18>>(geometry, view);
    case fcl::BV_KDOP24: return viewAs<fcl::KDOP<double, 24>>(geometry, view);
    default: return false;
  }
}

Fingerprint fingerprintOf(const MeshView& view) {
  Fingerprint f;
  f.vertices = view.vertices;
  f.triangles = view.triangles;
  f.num_vertices = view.num_vertices;
  f.num_triangles = view.num_triangles;
  f.build_state = view.build_state;
  for (int i = 0; i < kSampledVertices; ++i) {
    // Evenly spread, first and last included.
    const std::int64_t k =
        view.num_vertices <= 1 ? 0 : std::int64_t(i) * (view.num_vertices - 1) / (kSampledVertices - 1);
    f.samples[i] = view.num_vertices > 0 ? view.vertices[k] : fcl::Vector3d::Zero();
  }
  return f;
}

cfl::MeshModel copyMesh(const MeshView& view) {
  if (view.vertices == nullptr || view.triangles == nullptr || view.num_triangles <= 0 || view.num_vertices <= 0)
    throw cfl::Error("fcl::BVHModel met by a CFLGeometry has no triangles (num_tris " +
                     std::to_string(view.num_triangles) + ", num_vertices " + std::to_string(view.num_vertices) +
                     "); call beginModel/addSubModel/endModel first");
  cfl::TriangleMesh mesh;
  mesh.vertices.assign(view.vertices, view.vertices + view.num_vertices);
  mesh.triangles.resize(view.num_triangles);
  for (int t = 0; t < view.num_triangles; ++t)
    for (int c = 0; c < 3; ++c) {
      const std::size_t id = view.triangles[t][c];
      // Out-of-range ids are reported by makeMeshModel; only ids that do not fit an int need catching here.
      mesh.triangles[t][c] = id > std::size_t(INT_MAX) ? -1 : int(id);
    }
  try {
    return cfl::makeMeshModel(std::move(mesh));
  } catch (const cfl::Error& e) {
    throw cfl::Error(std::string("fcl::BVHModel met by a CFLGeometry: ") + e.what());
  }
}

struct Entry {
  std::weak_ptr<const Geometry> owner;  // Empty when only raw-pointer queries have met the model.
  bool has_owner = false;
  Fingerprint fingerprint;
  std::shared_ptr<const cfl::MeshModel> mesh;
  std::uint64_t last_use = 0;
};

struct Cache {
  std::mutex mutex;
  std::unordered_map<const Geometry*, Entry> entries;
  std::uint64_t clock = 0;
};

Cache& cache() {
  static Cache* instance = new Cache;  // Never destroyed: queries from static destructors stay safe.
  return *instance;
}

bool sameOwner(const std::weak_ptr<const Geometry>& a, const std::shared_ptr<const Geometry>& b) {
  return !a.owner_before(b) && !b.owner_before(a);
}

// Whether `entry` still describes the object now at `geometry` (before comparing contents).
bool sameObject(const Entry& entry, const Geometry* geometry, const std::shared_ptr<const Geometry>* owner) {
  if (!entry.has_owner) return true;  // Nothing more to go on: the fingerprint decides.
  if (owner != nullptr) return sameOwner(entry.owner, *owner);
  const std::shared_ptr<const Geometry> alive = entry.owner.lock();
  return alive != nullptr && alive.get() == geometry;
}

void trim(Cache& c) {
  if (c.entries.size() <= kMaxEntries) return;
  for (auto it = c.entries.begin(); it != c.entries.end();)
    it = (it->second.has_owner && it->second.owner.expired()) ? c.entries.erase(it) : std::next(it);
  while (c.entries.size() > kMaxEntries) {
    auto oldest = std::min_element(c.entries.begin(), c.entries.end(), [](const auto& a, const auto& b) {
      return a.second.last_use < b.second.last_use;
    });
    c.entries.erase(oldest);
  }
}

}  // namespace

std::shared_ptr<const cfl::MeshModel> bvhMeshModel(const Geometry* geometry,
                                                   const std::shared_ptr<const Geometry>* owner) {
  MeshView view;
  if (!viewOf(geometry, &view)) return nullptr;
  const Fingerprint now = fingerprintOf(view);
  Cache& c = cache();
  {
    std::lock_guard<std::mutex> lock(c.mutex);
    auto it = c.entries.find(geometry);
    if (it != c.entries.end() && sameObject(it->second, geometry, owner) && it->second.fingerprint == now) {
      Entry& entry = it->second;
      if (!entry.has_owner && owner != nullptr && *owner != nullptr) {
        entry.owner = *owner;
        entry.has_owner = true;
      }
      entry.last_use = ++c.clock;
      return entry.mesh;
    }
  }
  // Built outside the lock so other pairs are not held up; two threads racing here both build, one keeps.
  auto mesh = std::make_shared<const cfl::MeshModel>(copyMesh(view));
  std::lock_guard<std::mutex> lock(c.mutex);
  Entry& entry = c.entries[geometry];
  entry.owner.reset();
  entry.has_owner = owner != nullptr && *owner != nullptr;
  if (entry.has_owner) entry.owner = *owner;
  entry.fingerprint = now;
  entry.mesh = mesh;
  entry.last_use = ++c.clock;
  trim(c);
  return mesh;
}

}  // namespace detail

void forgetBvhModel(const fcl::CollisionGeometry<double>& model) {
  detail::Cache& c = detail::cache();
  std::lock_guard<std::mutex> lock(c.mutex);
  c.entries.erase(&model);
}

void clearBvhModelCache() {
  detail::Cache& c = detail::cache();
  std::lock_guard<std::mutex> lock(c.mutex);
  c.entries.clear();
}

}  // namespace cfl_fcl
