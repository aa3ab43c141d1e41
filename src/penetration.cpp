#include "cfl/penetration.h"

#include "cfl/cfl_query.h"
#include "cfl/error.h"
#include "cfl/point_query.h"
#include "cfl/triangle_distance.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <queue>
#include <sstream>
#include <vector>

namespace cfl {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();
// Signed point queries made before the search stops splitting triangles (it still returns a certified
// interval, wider than asked): a bound on time and memory whatever the meshes.
constexpr std::int64_t kMostEvaluations = 4'000'000;

// One direction of the search: the surface of `skin` (its triangles moved into the solid's frame) measured
// against the body of `solid`.
struct Direction {
  const CflModel* solid;
  const CflModel* skin;
  Eigen::Isometry3d X_SolidSkin;  // skin frame -> solid frame
  Eigen::Isometry3d X_WSolid;
};

// The signed distance to the solid at one point of the skin, frame of the solid.
struct Sample {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  double signed_distance = 0;
  Eigen::Vector3d closest = Eigen::Vector3d::Zero();
  int triangle = -1;  // of the solid
};

// What the search queues, with a bound on the depth over it: a node of the skin's Bvh (node >= 0: its
// bounding sphere; corners unused) or a piece of one of the skin's triangles.
struct Piece {
  double upper = 0;  // bound on the depth of every point of the piece inside the solid
  int direction = 0;
  Eigen::Vector3d center = Eigen::Vector3d::Zero();  // a node's sphere center (solid frame) and signed distance
  double center_signed_distance = 0;
  int node = -1;
  int skin_triangle = -1;
  Sample corner[3];
  double radius = 0;
};

struct ByUpper {
  bool operator()(const Piece& x, const Piece& y) const { return x.upper < y.upper; }
};

// The smallest ball holding the triangle: centered on the longest edge for a right or obtuse triangle, at the
// circumcenter otherwise. Its center lies in the triangle, so the signed distance there is attained.
void smallestBall(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, Eigen::Vector3d& center,
                  double& radius) {
  const Eigen::Vector3d v[3] = {a, b, c};
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d& p = v[k];
    const Eigen::Vector3d& q = v[(k + 1) % 3];
    const Eigen::Vector3d& r = v[(k + 2) % 3];
    // The angle at r is right or obtuse: the edge p-q is the diameter.
    if ((p - r).dot(q - r) <= 0) {
      center = 0.5 * (p + q);
      radius = 0.5 * (p - q).norm();
      return;
    }
  }
  const Eigen::Vector3d ab = b - a, ac = c - a;
  const Eigen::Vector3d n = ab.cross(ac);
  const double n2 = n.squaredNorm();
  if (!(n2 > 0)) {  // unreachable for acute triangles, kept for safety
    center = (a + b + c) / 3;
    radius = std::max({(a - center).norm(), (b - center).norm(), (c - center).norm()});
    return;
  }
  center = a + (ac.squaredNorm() * n.cross(ab) + ab.squaredNorm() * ac.cross(n)) / (2 * n2);
  radius = std::max({(a - center).norm(), (b - center).norm(), (c - center).norm()});
}

class PenetrationSearch {
 public:
  PenetrationSearch(const Direction* directions, double tolerance) : directions_(directions), tolerance_(tolerance) {
    options_.signed_distance = true;
  }

  // The signed distance at p, a point of skin triangle `skin_triangle`, or of no triangle when it is -1 (a
  // Bvh node's center): only points of the skin can be the deepest point.
  Sample sample(int direction, const Eigen::Vector3d& p, int skin_triangle) {
    ++evaluations_;
    const Direction& d = directions_[direction];
    const PointDistance r = computePointDistance(*d.solid, Eigen::Isometry3d::Identity(), p, options_);
    Sample s;
    s.p = p;
    s.signed_distance = r.distance;
    s.closest = r.closest_point;
    s.triangle = r.triangle;
    if (skin_triangle >= 0) noteDepth(direction, skin_triangle, s);
    return s;
  }

  // Records a point of a skin inside the solid as the deepest so far when it is.
  void noteDepth(int direction, int skin_triangle, const Sample& s) {
    if (s.signed_distance < 0 && -s.signed_distance > best_) {
      best_ = -s.signed_distance;
      best_direction_ = direction;
      best_sample_ = s;
      best_skin_triangle_ = skin_triangle;
    }
  }

  // Upper bound on the depth of the piece's points that lie inside the solid, and false when no point of it
  // can be inside. The unsigned distance to the solid's surface is the minimum over its triangles of convex
  // functions, so over the piece it is at most min over triangles i of (max over the corners of dist to i);
  // the triangles closest to the corners are the candidates. The signed distance is 1-Lipschitz, which bounds
  // the depth by the center's depth plus the radius, and shows a piece wholly outside when the center is
  // farther out than the radius.
  bool bound(Piece& piece, const Sample& center) const {
    const Direction& d = directions_[piece.direction];
    const auto& corners = d.solid->geometry.corners;
    double convex = kInfinity;
    for (int k = 0; k < 3; ++k) {
      const int t = piece.corner[k].triangle;
      if (t < 0 || (k > 0 && t == piece.corner[0].triangle) || (k > 1 && t == piece.corner[1].triangle)) continue;
      const auto& c = corners[t];
      double worst = 0;
      for (int j = 0; j < 3; ++j)
        worst = std::max(worst, pointTriangleSquaredDistance(piece.corner[j].p, c[0], c[1], c[2]));
      convex = std::min(convex, std::sqrt(worst));
    }
    if (center.signed_distance >= piece.radius) return false;
    piece.upper = std::min(convex, piece.radius - center.signed_distance);
    const double upper = piece.upper;
    return upper > 0;
  }

  void push(Piece&& piece) {
    if (piece.upper <= best_) return;
    queue_.push(std::move(piece));
  }

  // Splits the piece in four at its edge midpoints.
  void split(const Piece& piece) {
    Sample mid[3];
    for (int k = 0; k < 3; ++k)
      mid[k] = sample(piece.direction, 0.5 * (piece.corner[k].p + piece.corner[(k + 1) % 3].p), piece.skin_triangle);
    const Sample* children[4][3] = {{&piece.corner[0], &mid[0], &mid[2]},
                                    {&mid[0], &piece.corner[1], &mid[1]},
                                    {&mid[2], &mid[1], &piece.corner[2]},
                                    {&mid[0], &mid[1], &mid[2]}};
    for (auto& child_corners : children) {
      Piece child;
      child.direction = piece.direction;
      child.skin_triangle = piece.skin_triangle;
      for (int k = 0; k < 3; ++k) child.corner[k] = *child_corners[k];
      Eigen::Vector3d center;
      smallestBall(child.corner[0].p, child.corner[1].p, child.corner[2].p, center, child.radius);
      const Sample c = sample(child.direction, center, child.skin_triangle);
      if (bound(child, c)) push(std::move(child));
    }
  }

  // Queues the root of a skin's Bvh.
  void start(int direction) {
    const Direction& d = directions_[direction];
    if (d.skin->geometry.bvh.nodes.empty()) return;
    vertex_samples_[direction].assign(d.skin->geometry.mesh.vertices.size(), Sample{});
    pushNode(direction, 0, nullptr);
  }

  // A Bvh node of the skin: every point of it lies within its sphere (center c, radius r), and the signed
  // distance is 1-Lipschitz, so no point of it is deeper than -sd(c) + r, and none is inside when
  // sd(c) >= r.
  void pushNode(int direction, int index, const Piece* parent) {
    const Direction& d = directions_[direction];
    const BvhNode& node = d.skin->geometry.bvh.nodes[index];
    const Eigen::Vector3d center = d.X_SolidSkin * node.center;
    if (parent != nullptr) {
      // The parent's sample bounds the child's center's without a query: sd(c) >= sd(parent) - |c - parent|.
      const double at_least = parent->center_signed_distance - (center - parent->center).norm();
      if (at_least >= node.radius || node.radius - at_least <= best_) return;
    }
    const Sample c = sample(direction, center, -1);
    if (c.signed_distance >= node.radius) return;
    Piece piece;
    piece.direction = direction;
    piece.node = index;
    piece.radius = node.radius;
    piece.center = center;
    piece.center_signed_distance = c.signed_distance;
    piece.upper = node.radius - c.signed_distance;
    push(std::move(piece));
  }

  // The corners of the skin's triangles are shared: each vertex is sampled once per direction (as a point
  // of the first triangle met that has it).
  const Sample& vertexSample(int direction, int v, int skin_triangle) {
    Sample& s = vertex_samples_[direction][v];
    if (s.triangle < 0) {
      const Direction& d = directions_[direction];
      s = sample(direction, d.X_SolidSkin * d.skin->geometry.mesh.vertices[v], skin_triangle);
    }
    return s;
  }

  void expand(const Piece& piece) {
    const Direction& d = directions_[piece.direction];
    const MeshModel& skin = d.skin->geometry;
    const BvhNode& node = skin.bvh.nodes[piece.node];
    if (!node.isLeaf()) {
      pushNode(piece.direction, node.first, &piece);
      pushNode(piece.direction, node.first + 1, &piece);
      return;
    }
    for (int i = node.first; i < node.first + node.count; ++i) {
      const int t = skin.bvh.triangle_ids[i];
      Piece triangle;
      triangle.direction = piece.direction;
      triangle.skin_triangle = t;
      for (int k = 0; k < 3; ++k) triangle.corner[k] = vertexSample(piece.direction, skin.mesh.triangles[t][k], t);
      Eigen::Vector3d center;
      smallestBall(triangle.corner[0].p, triangle.corner[1].p, triangle.corner[2].p, center, triangle.radius);
      const Sample c = sample(piece.direction, center, t);
      if (bound(triangle, c)) push(std::move(triangle));
    }
  }


  // Runs the branch and bound; returns the certified upper end.
  double run(double smallest_radius) {
    double settled = 0;  // upper bounds of pieces too small to split further
    while (!queue_.empty()) {
      const double top = queue_.top().upper;
      if (top <= best_ + tolerance_) return std::max({best_, top, settled});
      Piece piece = queue_.top();
      queue_.pop();
      if (piece.upper <= best_) continue;
      if (piece.node < 0 && (piece.radius <= smallest_radius || evaluations_ > kMostEvaluations)) {
        settled = std::max(settled, piece.upper);
        continue;
      }
      if (piece.node >= 0) expand(piece);
      else split(piece);
    }
    return std::max(best_, settled);
  }

  double best() const { return best_; }
  int bestDirection() const { return best_direction_; }
  const Sample& bestSample() const { return best_sample_; }
  int bestSkinTriangle() const { return best_skin_triangle_; }

 private:
  const Direction* directions_;
  double tolerance_;
  PointQueryOptions options_;
  std::priority_queue<Piece, std::vector<Piece>, ByUpper> queue_;
  double best_ = 0;
  int best_direction_ = -1;
  Sample best_sample_;
  int best_skin_triangle_ = -1;
  std::int64_t evaluations_ = 0;
  std::vector<Sample> vertex_samples_[2];
};

void requireClosed(const CflModel& model, const char* name) {
  if (!model.sign.closure.closed)
    throw Error(std::string("mesh ") + name + " does not bound a solid, so it has no inside and no depth: " +
                model.sign.closure.reason);
}

}  // namespace

PenetrationResult computePenetration(const CflModel& a, const Eigen::Isometry3d& X_WA, const CflModel& b,
                                     const Eigen::Isometry3d& X_WB, const PenetrationOptions& options) {
  validatePose(X_WA, "X_WA");
  validatePose(X_WB, "X_WB");
  if (!(options.tolerance >= 0) || !std::isfinite(options.tolerance)) {
    std::ostringstream message;
    message << "computePenetration: tolerance must be a finite length >= 0 (0: 1e-4 of the larger diagonal), got "
            << options.tolerance;
    throw Error(message.str());
  }
  requireClosed(a, "A");
  requireClosed(b, "B");
  const double diagonal = std::max(a.geometry.bounds.diagonal(), b.geometry.bounds.diagonal());
  const double tolerance = options.tolerance > 0 ? options.tolerance : 1e-4 * diagonal;

  // Whether the surfaces meet; with closed surfaces that do not, the bodies overlap only when one holds
  // the other, which one vertex of each tells.
  std::vector<Contact> contacts;
  computeCollision(a.geometry, X_WA, b.geometry, X_WB, 1, &contacts);
  const Direction directions[2] = {{&a, &b, X_WA.inverse() * X_WB, X_WA}, {&b, &a, X_WB.inverse() * X_WA, X_WB}};
  PenetrationSearch search(directions, tolerance);
  PenetrationResult result;
  if (contacts.empty()) {
    result.contained = bodyContainment(a, X_WA, b, X_WB);
    if (result.contained == 0) return result;
  }
  result.overlapping = true;
  for (int direction = 0; direction < 2; ++direction) search.start(direction);
  // Pieces smaller than this are not split: the interval then stays as wide as their bounds (certified still).
  const double smallest_radius = 1e-9 * diagonal;
  const double upper = search.run(smallest_radius);

  result.depth = search.best();
  result.depth_upper = std::max(upper, result.depth);
  const int direction = search.bestDirection();
  if (direction < 0) {
    // The surfaces touch but no point of either is strictly inside the other: depth 0 at a contact point.
    const Contact& c = contacts.front();
    result.deepest_point = result.surface_point = c.position;
    result.deepest_body = 1;
    result.triangle_a = c.triangle_a;
    result.triangle_b = c.triangle_b;
    return result;
  }
  const Direction& d = directions[direction];
  const Sample& s = search.bestSample();
  result.deepest_body = direction == 0 ? 1 : 0;  // direction 0 measures B's surface against A
  result.deepest_point = d.X_WSolid * s.p;
  result.surface_point = d.X_WSolid * s.closest;
  const Eigen::Vector3d out = result.surface_point - result.deepest_point;
  const double length = out.norm();
  if (length > 0) {
    result.normal = out / length;
  } else {
    const PointDistance at = computePointDistance(*d.solid, d.X_WSolid, result.surface_point,
                                                  PointQueryOptions{true, SignMethod::kAuto});
    result.normal = at.gradient;
  }
  const int skin_triangle = search.bestSkinTriangle();
  if (direction == 0) {
    result.triangle_a = s.triangle;
    result.triangle_b = skin_triangle;
  } else {
    result.triangle_b = s.triangle;
    result.triangle_a = skin_triangle;
  }
  return result;
}

int bodyContainment(const CflModel& a, const Eigen::Isometry3d& X_WA, const CflModel& b,
                    const Eigen::Isometry3d& X_WB) {
  requireClosed(a, "A");
  requireClosed(b, "B");
  PointQueryOptions signed_query;
  signed_query.signed_distance = true;
  const auto inside = [&](const CflModel& solid, const Eigen::Isometry3d& X_WSolid, const CflModel& skin,
                          const Eigen::Isometry3d& X_WSkin) {
    const int v = skin.geometry.mesh.triangles.front()[0];
    return computePointDistance(solid, X_WSolid, X_WSkin * skin.geometry.mesh.vertices[v], signed_query).distance < 0;
  };
  if (inside(a, X_WA, b, X_WB)) return 1;
  if (inside(b, X_WB, a, X_WA)) return 2;
  return 0;
}

DistanceResult computeSignedDistance(const CflModel& a, const Eigen::Isometry3d& X_WA, const CflModel& b,
                                     const Eigen::Isometry3d& X_WB, const DistanceOptions& options,
                                     const PenetrationOptions& penetration) {
  requireClosed(a, "A");
  requireClosed(b, "B");
  const DistanceResult apart = computeDistance(a, X_WA, b, X_WB, options);
  const bool touching = apart.triangle_a >= 0 && apart.distance == 0;
  if (!touching && bodyContainment(a, X_WA, b, X_WB) == 0) return apart;
  const PenetrationResult p = computePenetration(a, X_WA, b, X_WB, penetration);
  DistanceResult result;
  result.distance = -p.depth;
  result.point_a = p.deepest_body == 0 ? p.deepest_point : p.surface_point;
  result.point_b = p.deepest_body == 0 ? p.surface_point : p.deepest_point;
  result.triangle_a = p.triangle_a;
  result.triangle_b = p.triangle_b;
  return result;
}

}  // namespace cfl
