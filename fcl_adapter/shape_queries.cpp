// Primitive shapes against a CFL geometry, answered from the CFL model instead of FCL's traversal of the
// OBBRSS twin:
//   - sphere: the distance of its center minus its radius; capsule: of its segment minus its radius
//     (cfl::computeSegmentDistance, a point being a segment of length 0);
//   - box: cfl::computeBoxDistance; convex: the mesh-mesh query against its triangles (shape_mesh_cache.cpp),
//     plus a test for mesh triangles lying wholly inside the solid shape, which touch no face;
//   - signed requests on closed meshes: negative inside (signed point and segment queries for spheres and
//     capsules, the penetration query against the shape's own CflModel for boxes and convexes).
//
// Where FCL's answer is kept: when the shape touches or overlaps the mesh and the request is unsigned (or the
// mesh is not closed, so it has no inside), the pair goes to FCL's own shape-mesh algorithm on the twin.
// FCL 0.7 has no defined answer there (sphereTriangleDistance leaves the distance unset when nearest
// points are asked for and returns -1 otherwise; GJK-based shapes return -1 or 0 depending on the solver),
// and programs compare it with FCL's (the acceptance program compares sphere-vs-CFL with sphere-vs-BVHModel
// on penetrating poses), so the adapter reproduces it rather than inventing a number.

#include "adapter_internal.h"

#include <cfl/box_query.h>
#include <cfl/cfl_query.h>
#include <cfl/penetration.h>
#include <cfl/point_query.h>
#include <cfl/segment_query.h>
#include <cfl/triangle_distance.h>

#include <fcl/geometry/shape/box.h>
#include <fcl/geometry/shape/capsule.h>
#include <fcl/geometry/shape/sphere.h>

#include <algorithm>
#include <limits>
#include <vector>

namespace cfl_fcl::detail {
namespace {

using Geometry = fcl::CollisionGeometry<double>;
using Transform = fcl::Transform3<double>;

// A sphere or capsule as the points within `radius` of the segment [p0, p1] (world frame).
struct Swept {
  Eigen::Vector3d p0, p1;
  double radius = 0;
};

bool asSwept(const Geometry& shape, const Transform& tf_s, Swept* swept) {
  if (shape.getNodeType() == fcl::GEOM_SPHERE) {
    swept->p0 = swept->p1 = tf_s.translation();
    swept->radius = static_cast<const fcl::Sphere<double>&>(shape).radius;
    return true;
  }
  if (shape.getNodeType() == fcl::GEOM_CAPSULE) {
    const auto& capsule = static_cast<const fcl::Capsule<double>&>(shape);
    // FCL's capsule: axis z of its frame, centered, the segment lz long.
    swept->p0 = tf_s * Eigen::Vector3d(0, 0, -0.5 * capsule.lz);
    swept->p1 = tf_s * Eigen::Vector3d(0, 0, 0.5 * capsule.lz);
    swept->radius = capsule.radius;
    return true;
  }
  return false;
}

// FCL's result.min_distance as an upper bound: DBL_MAX means none.
double boundOf(const fcl::DistanceResult<double>& result) {
  return result.min_distance < std::numeric_limits<double>::max() ? result.min_distance
                                                                  : std::numeric_limits<double>::infinity();
}

// Shape-mesh pairs as FCL records them: the mesh is o1 with b1 its triangle, the shape o2 with b2 NONE,
// whichever order the caller passed them in; nearest_points[0] on the mesh, [1] on the shape, world frame.
void record(double distance, const Geometry& cfl, const Geometry& shape, int triangle, const Eigen::Vector3d& on_mesh,
            const Eigen::Vector3d& on_shape, const fcl::DistanceRequest<double>& request,
            fcl::DistanceResult<double>& result) {
  if (request.enable_nearest_points)
    result.update(distance, &cfl, &shape, triangle, fcl::DistanceResult<double>::NONE, on_mesh, on_shape);
  else
    result.update(distance, &cfl, &shape, triangle, fcl::DistanceResult<double>::NONE);
}

// Whether a triangle of the mesh lies wholly inside the solid convex shape (then it touches no face, and the
// surfaces' distance says nothing). A triangle inside has its first corner inside, and that corner lies in
// the shape's bounding box, so the mesh's Bvh is walked only where it meets that box.
bool meshTriangleInside(const cfl::MeshModel& mesh, const Transform& tf_c, const ShapeMesh& shape,
                        const Transform& tf_s) {
  const Eigen::Isometry3d X_SM = Eigen::Isometry3d(tf_s.inverse() * tf_c);
  const Eigen::Isometry3d X_MS = X_SM.inverse();
  cfl::Aabb box_M;
  const cfl::Aabb& box_S = shape.mesh->bounds;
  for (int k = 0; k < 8; ++k)
    box_M.extend(X_MS * Eigen::Vector3d(k & 1 ? box_S.max.x() : box_S.min.x(), k & 2 ? box_S.max.y() : box_S.min.y(),
                                        k & 4 ? box_S.max.z() : box_S.min.z()));
  const auto& nodes = mesh.bvh.nodes;
  if (nodes.empty()) return false;
  int stack[128];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const cfl::BvhNode& node = nodes[stack[--top]];
    if ((node.box().min.array() > box_M.max.array()).any() || (node.box().max.array() < box_M.min.array()).any())
      continue;
    if (node.isLeaf()) {
      for (int i = node.first; i < node.first + node.count; ++i)
        if (shape.contains(X_SM * mesh.corners.in_leaf_order[i][0])) return true;
      continue;
    }
    stack[top++] = node.first + 1;
    stack[top++] = node.first;
  }
  return false;
}

// Whether the request wants, and the mesh has, a signed distance. A mesh that is not closed has no inside:
// FCL's own answer stands for it.
bool signable(const fcl::DistanceRequest<double>& request, const cfl::CflModel& model) {
  return request.enable_signed_distance && model.sign.closure.closed;
}

// The (signed, on a closed mesh when asked) distance of a sphere's center or a capsule's segment: the point
// query through its leaf for a sphere, the segment query for a capsule. `bound` as in SegmentQueryOptions.
cfl::SegmentDistance sweptDistance(const cfl::CflModel& model, const Transform& tf_c, const Swept& swept,
                                   bool signed_distance, double bound) {
  const Eigen::Isometry3d X_WM(tf_c);
  if (swept.p0 == swept.p1) {
    cfl::PointQueryOptions options;
    options.signed_distance = signed_distance;
    // A signed query must not be bounded: a center deep inside is far from every triangle, yet closest.
    if (!signed_distance) options.upper_bound = bound;
    const cfl::PointDistance d = cfl::computePointDistance(model, X_WM, swept.p0, options);
    cfl::SegmentDistance s;
    if (d.triangle < 0) return s;
    s.distance = d.distance;
    s.segment_point = swept.p0;
    s.mesh_point = d.closest_point;
    s.direction = d.gradient;
    s.triangle = d.triangle;
    return s;
  }
  cfl::SegmentQueryOptions options;
  options.signed_distance = signed_distance;
  options.upper_bound = bound;
  return cfl::computeSegmentDistance(model, X_WM, swept.p0, swept.p1, options);
}

// Contacts of a box or convex with the mesh, one per mesh triangle that meets the solid shape (up to
// `budget`), as FCL reports them: a triangle meets it when a corner lies inside or it crosses one of the
// shape's faces (exact tests, cfl::trianglesIntersect). Only triangles in the shape's bounding box can, so the
// mesh's Bvh is walked where it meets that box. On a closed mesh, a shape wholly inside collides too. The
// contact point is a point of both; the normal the triangle's, turned towards the shape's center (from o1 to
// o2); the depth is the pair's penetration depth on a closed mesh (cfl::computePenetration's certified lower
// end, the same for every contact of the pair), not computed (0) on other meshes, as for the adapter's mesh
// pairs, and the depth of the shape's deepest vertex when it lies wholly inside a closed mesh.
void polyhedronContacts(const Geometry& cfl, const cfl::CflModel& model, const Transform& tf_c, const Geometry& shape,
                        const ShapeMesh& polyhedron, const Transform& tf_s,
                        const fcl::CollisionRequest<double>& request, std::size_t budget,
                        fcl::CollisionResult<double>& result) {
  if (budget == 0) return;
  const cfl::MeshModel& mesh = model.geometry;
  const Eigen::Isometry3d X_SM = Eigen::Isometry3d(tf_s.inverse() * tf_c);
  const Eigen::Isometry3d X_MS = X_SM.inverse();
  cfl::Aabb box_M;
  const cfl::Aabb& box_S = polyhedron.mesh->bounds;
  for (int k = 0; k < 8; ++k)
    box_M.extend(X_MS * Eigen::Vector3d(k & 1 ? box_S.max.x() : box_S.min.x(), k & 2 ? box_S.max.y() : box_S.min.y(),
                                        k & 4 ? box_S.max.z() : box_S.min.z()));
  const Eigen::Vector3d center_W = tf_s * box_S.center();
  std::size_t added = 0;
  auto add = [&](int triangle, const Eigen::Vector3d& p_W, const Eigen::Vector3d& normal_W, double depth) {
    if (request.enable_contact)
      result.addContact(fcl::Contact<double>(&cfl, &shape, triangle, fcl::Contact<double>::NONE, p_W, normal_W, depth));
    else
      result.addContact(fcl::Contact<double>(&cfl, &shape, triangle, fcl::Contact<double>::NONE));
    ++added;
  };
  // On a closed mesh the pair has a penetration depth (the shape's own CflModel against the mesh, once per
  // call, only when contacts carry depths); elsewhere a touching triangle's depth is not computed (0).
  double pair_depth = 0;
  bool depth_known = !request.enable_contact || !model.sign.closure.closed;
  auto depthOfPair = [&]() {
    if (!depth_known) {
      depth_known = true;
      const cfl::CflModel& solid = polyhedron.solid();
      if (solid.sign.closure.closed)
        pair_depth = cfl::computePenetration(model, Eigen::Isometry3d(tf_c), solid, Eigen::Isometry3d(tf_s)).depth;
    }
    return pair_depth;
  };
  const auto& nodes = mesh.bvh.nodes;
  const auto& faces = polyhedron.mesh->corners;
  int stack[128];
  int top = 0;
  if (!nodes.empty()) stack[top++] = 0;
  while (top > 0 && added < budget) {
    const cfl::BvhNode& node = nodes[stack[--top]];
    if ((node.box().min.array() > box_M.max.array()).any() || (node.box().max.array() < box_M.min.array()).any())
      continue;
    if (!node.isLeaf()) {
      stack[top++] = node.first + 1;
      stack[top++] = node.first;
      continue;
    }
    for (int i = node.first; i < node.first + node.count && added < budget; ++i) {
      const auto& c = mesh.corners.in_leaf_order[i];
      const Eigen::Vector3d t_S[3] = {X_SM * c[0], X_SM * c[1], X_SM * c[2]};
      Eigen::Vector3d point_S = t_S[0];
      bool hit = polyhedron.contains(t_S[0]);
      for (std::size_t f = 0; f < faces.size() && !hit; ++f) {
        const Eigen::Vector3d face[3] = {faces[f][0], faces[f][1], faces[f][2]};
        hit = cfl::trianglesIntersect(t_S, face, &point_S);
      }
      if (!hit) continue;
      Eigen::Vector3d normal = tf_c.linear() * (c[1] - c[0]).cross(c[2] - c[0]);
      const double length = normal.norm();
      normal = length > 0 ? Eigen::Vector3d(normal / length) : Eigen::Vector3d::Zero();
      const Eigen::Vector3d p_W = tf_s * point_S;
      if (normal.dot(center_W - p_W) < 0) normal = -normal;
      add(mesh.bvh.triangle_ids[i], p_W, normal, depthOfPair());
    }
  }
  if (added > 0 || !model.sign.closure.closed) return;
  // Touching no triangle: inside the closed mesh or apart, and a vertex says which.
  cfl::PointQueryOptions options;
  options.signed_distance = true;
  double deepest = 0;
  cfl::PointDistance at;
  Eigen::Vector3d vertex_W = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& v : polyhedron.mesh->mesh.vertices) {
    const Eigen::Vector3d v_W = tf_s * v;
    const cfl::PointDistance d = cfl::computePointDistance(model, Eigen::Isometry3d(tf_c), v_W, options);
    if (!(d.distance < 0)) return;  // Not inside (one vertex out and no crossing: all out).
    if (-d.distance > deepest) {
      deepest = -d.distance;
      at = d;
      vertex_W = v_W;
    }
  }
  if (at.triangle >= 0) add(at.triangle, vertex_W, at.gradient, deepest);
}

// A signed request on a closed mesh with a box or convex that overlaps it or lies inside it: minus the
// penetration depth (cfl::computeSignedDistance against the shape's own CflModel, built once per shape; its
// certified lower end), nearest points the deepest point and its closest point on the other surface. A shape
// whose faces do not close up (a malformed Convex) has no inside: false, FCL's answer.
bool signedPolyhedron(const Geometry& cfl, const cfl::CflModel& model, const Transform& tf_c, const Geometry& shape,
                      const Transform& tf_s, const fcl::DistanceRequest<double>& request,
                      fcl::DistanceResult<double>& result) {
  const auto polyhedron = shapeMesh(shape);
  if (polyhedron == nullptr) return false;
  const cfl::CflModel& solid = polyhedron->solid();
  if (!solid.sign.closure.closed) return false;
  cfl::DistanceOptions options;
  options.rel_err = request.rel_err;
  options.abs_err = request.abs_err;
  const cfl::DistanceResult d =
      cfl::computeSignedDistance(model, Eigen::Isometry3d(tf_c), solid, Eigen::Isometry3d(tf_s), options);
  if (d.triangle_a < 0) return true;
  record(d.distance, cfl, shape, d.triangle_a, d.point_a, d.point_b, request, result);
  return true;
}

}  // namespace

bool shapeDistance(const Geometry& cfl, const cfl::CflModel& model, const Transform& tf_c, const Geometry& shape,
                   const Transform& tf_s, const fcl::DistanceRequest<double>& request,
                   fcl::DistanceResult<double>& result) {
  const double bound = boundOf(result);
  Swept swept;
  if (asSwept(shape, tf_s, &swept)) {
    // A pair that cannot beat the result's distance is dropped by FCL's update; the query may dismiss it as
    // soon as its bounds show that (the shape's surface is `radius` closer than its center or segment).
    const bool signed_distance = signable(request, model);
    const cfl::SegmentDistance d = sweptDistance(model, tf_c, swept, signed_distance, bound + swept.radius);
    if (d.triangle < 0) return true;  // Not closer than the result's pair: FCL would keep the result as it is.
    // Unsigned and touching: FCL's answer (see the top of this file).
    if (!(d.distance > swept.radius) && !signed_distance) return false;
    // The shape's point nearest the mesh (outside) or deepest in it (inside): |on_shape - mesh_point| is
    // |distance - radius| either way, since `direction` points from the mesh point to the segment point
    // outside and outward inside.
    record(d.distance - swept.radius, cfl, shape, d.triangle, d.mesh_point,
           d.segment_point - swept.radius * d.direction, request, result);
    return true;
  }
  if (shape.getNodeType() == fcl::GEOM_BOX) {
    // The box's own query: the mesh's Bvh against the box's faces, edges and corners, exact.
    const auto& box = static_cast<const fcl::Box<double>&>(shape);
    const cfl::BoxDistance d =
        cfl::computeBoxDistance(model, Eigen::Isometry3d(tf_c), Eigen::Isometry3d(tf_s), 0.5 * box.side, bound);
    if (d.triangle < 0) return true;  // Nothing closer than the result's pair, and nothing touching.
    const bool signed_distance = signable(request, model);
    if (!(d.distance > 0))
      return signed_distance && signedPolyhedron(cfl, model, tf_c, shape, tf_s, request, result);
    // Apart from the surface; when signed, also outside the solid (the center says which).
    if (signed_distance &&
        cfl::computePointDistance(model, Eigen::Isometry3d(tf_c), tf_s.translation(), {true, cfl::SignMethod::kAuto})
                .distance < 0)
      return signedPolyhedron(cfl, model, tf_c, shape, tf_s, request, result);
    record(d.distance, cfl, shape, d.triangle, d.mesh_point, d.box_point, request, result);
    return true;
  }
  const auto polyhedron = shapeMesh(shape);
  if (polyhedron == nullptr) return false;
  cfl::DistanceOptions options;
  options.rel_err = request.rel_err;
  options.abs_err = request.abs_err;
  options.upper_bound = bound;
  const cfl::DistanceResult d =
      cfl::computeDistance(model, Eigen::Isometry3d(tf_c), *polyhedron->mesh, Eigen::Isometry3d(tf_s), options);
  const bool overlapping =
      (d.triangle_a >= 0 && d.distance == 0) || meshTriangleInside(model.geometry, tf_c, *polyhedron, tf_s);
  // A signed request on a closed mesh also needs the shape outside the solid; its surface not meeting the
  // mesh's, one vertex says. Overlapping or inside: minus the penetration depth.
  const bool signed_distance = signable(request, model);
  const bool inside_solid =
      !overlapping && signed_distance &&
      cfl::computePointDistance(model, Eigen::Isometry3d(tf_c), tf_s * polyhedron->mesh->mesh.vertices[0],
                                {true, cfl::SignMethod::kAuto})
              .distance < 0;
  if (overlapping || inside_solid)
    return signed_distance && signedPolyhedron(cfl, model, tf_c, shape, tf_s, request, result);
  if (d.triangle_a >= 0) record(d.distance, cfl, shape, d.triangle_a, d.point_a, d.point_b, request, result);
  return true;
}

bool shapeCollide(const Geometry& cfl, const cfl::CflModel& model, const Transform& tf_c, const Geometry& shape,
                  const Transform& tf_s, const fcl::CollisionRequest<double>& request,
                  fcl::CollisionResult<double>& result) {
  const std::size_t budget = request.num_max_contacts - std::min(request.num_max_contacts, result.numContacts());
  Swept swept;
  if (!asSwept(shape, tf_s, &swept)) {
    const auto polyhedron = shapeMesh(shape);
    if (polyhedron == nullptr) return false;
    polyhedronContacts(cfl, model, tf_c, shape, *polyhedron, tf_s, request, budget, result);
    return true;
  }
  std::vector<cfl::SegmentDistance> touching;
  cfl::findTrianglesNearSegment(model, Eigen::Isometry3d(tf_c), swept.p0, swept.p1, swept.radius, budget, &touching);
  // A closed mesh bounds a solid: a shape inside it collides although it touches no triangle, and every
  // contact's depth is the shape's depth in the solid (radius minus the signed distance of its core), not
  // how far it reaches past one triangle.
  const bool solid = model.sign.closure.closed;
  cfl::SegmentDistance core;
  if (solid && (touching.empty() || request.enable_contact))
    core = sweptDistance(model, tf_c, swept, true, std::numeric_limits<double>::infinity());
  if (touching.empty() && solid && core.triangle >= 0 && core.distance < 0 && budget > 0) {
    if (request.enable_contact)
      result.addContact(fcl::Contact<double>(&cfl, &shape, core.triangle, fcl::Contact<double>::NONE,
                                             core.segment_point, core.direction, swept.radius - core.distance));
    else
      result.addContact(fcl::Contact<double>(&cfl, &shape, core.triangle, fcl::Contact<double>::NONE));
  }
  for (const cfl::SegmentDistance& t : touching) {
    if (request.enable_contact) {
      // FCL's convention: the normal points from o1 (the mesh) to o2 (the shape), the direction that
      // separates them; the depth is how far the shape reaches past the triangle (into the solid, if any).
      const double depth = swept.radius - (solid ? std::min(core.distance, t.distance) : t.distance);
      result.addContact(fcl::Contact<double>(&cfl, &shape, t.triangle, fcl::Contact<double>::NONE, t.mesh_point,
                                             t.direction, depth));
    } else {
      result.addContact(fcl::Contact<double>(&cfl, &shape, t.triangle, fcl::Contact<double>::NONE));
    }
  }
  return true;
}

}  // namespace cfl_fcl::detail
