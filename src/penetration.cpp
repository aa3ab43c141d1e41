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
// Sub-triangles evaluated before the search gives up narrowing the interval (it still returns a certified
// one, wider than asked): a bound on time and memory whatever the meshes.
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
  Eigen::Vector3d p;
  double signed_distance = 0;
  Eigen::Vector3d closest = Eigen::Vector3d::Zero();
  int triangle = -1;  // of the solid
};

// A piece of a skin triangle, with what bounds the depth over it.
struct Piece {
  double upper = 0;  // bound on the depth of every point of the piece inside the solid
  int direction = 0;
  int skin_triangle = -1;
  int level = 0;
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

  Sample sample(int direction, const Eigen::Vector3d& p) {
    ++evaluations_;
    const Direction& d = directions_[direction];
    const PointDistance r = computePointDistance(*d.solid, Eigen::Isometry3d::Identity(), p, options_);
    Sample s;
    s.p = p;
    s.signed_distance = r.distance;
    s.closest = r.closest_point;
    s.triangle = r.triangle;
    noteDepth(direction, -1, s);
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
  bool bound(Piece& piece, const Sample* center) const {
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
    double upper = convex;
    if (center != nullptr) {
      if (center->signed_distance >= piece.radius) return false;
      upper = std::min(upper, -center->signed_distance + piece.radius);
    }
    piece.upper = upper;
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
      mid[k] = sample(piece.direction, 0.5 * (piece.corner[k].p + piece.corner[(k + 1) % 3].p));
    const Sample* children[4][3] = {{&piece.corner[0], &mid[0], &mid[2]},
                                    {&mid[0], &piece.corner[1], &mid[1]},
                                    {&mid[2], &mid[1], &piece.corner[2]},
                                    {&mid[0], &mid[1], &mid[2]}};
    for (auto& child_corners : children) {
      Piece child;
      child.direction = piece.direction;
      child.skin_triangle = piece.skin_triangle;
      child.level = piece.level + 1;
      for (int k = 0; k < 3; ++k) {
        child.corner[k] = *child_corners[k];
        noteDepthOf(child, k);
      }
      Eigen::Vector3d center;
      smallestBall(child.corner[0].p, child.corner[1].p, child.corner[2].p, center, child.radius);
      Sample c = sample(child.direction, center);
      noteDepthOfSample(child, c);
      if (bound(child, &c)) push(std::move(child));
    }
  }

  void noteDepthOf(const Piece& piece, int k) { noteDepth(piece.direction, piece.skin_triangle, piece.corner[k]); }
  void noteDepthOfSample(const Piece& piece, const Sample& s) { noteDepth(piece.direction, piece.skin_triangle, s); }

  // Runs the branch and bound; returns the certified upper end.
  double run(double smallest_radius) {
    double settled = 0;  // upper bounds of pieces too small to split further
    while (!queue_.empty()) {
      const double top = queue_.top().upper;
      if (top <= best_ + tolerance_) return std::max({best_, top, settled});
      Piece piece = queue_.top();
      queue_.pop();
      if (piece.upper <= best_) continue;
      if (piece.radius <= smallest_radius || evaluations_ > kMostEvaluations) {
        settled = std::max(settled, piece.upper);
        continue;
      }
      split(piece);
    }
    return std::max(best_, settled);
  }

  double best() const { return best_; }
  int bestDirection() const { return best_direction_; }
  const Sample& bestSample() const { return best_sample_; }
  int bestSkinTriangle() const { return best_skin_triangle_; }
  void setBestSkinTriangle(int t) { best_skin_triangle_ = t; }

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
};

void requireClosed(const CflModel& model, const char* name) {
  if (!model.sign.closure.closed)
    throw Error(std::string("computePenetration: mesh ") + name +
                " does not bound a solid, so no point is inside it: " + model.sign.closure.reason);
}

// The skin triangle holding point p (frame of the solid) among the triangles of the piece's skin: the one
// the search started from when known, else the nearest one.
int skinTriangleOf(const CflModel& skin, const Eigen::Isometry3d& X_SolidSkin, const Eigen::Vector3d& p_Solid) {
  const Eigen::Vector3d p_Skin = X_SolidSkin.inverse() * p_Solid;
  const PointDistance r = computePointDistance(skin, Eigen::Isometry3d::Identity(), p_Skin);
  return r.triangle;
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

  // Which triangles of each surface meet the other surface: the others lie wholly inside or wholly outside
  // the other body, which one corner's sign tells.
  std::vector<Contact> contacts;
  computeCollision(a.geometry, X_WA, b.geometry, X_WB, std::numeric_limits<std::size_t>::max(), &contacts);
  std::vector<char> crossing[2];  // [0]: B's triangles (skin of direction 0), [1]: A's
  crossing[0].assign(b.geometry.corners.size(), 0);
  crossing[1].assign(a.geometry.corners.size(), 0);
  for (const Contact& c : contacts) {
    crossing[0][c.triangle_b] = 1;
    crossing[1][c.triangle_a] = 1;
  }

  const Direction directions[2] = {{&a, &b, X_WA.inverse() * X_WB, X_WA}, {&b, &a, X_WB.inverse() * X_WA, X_WB}};
  PenetrationSearch search(directions, tolerance);
  bool inside_vertex[2] = {false, false};  // some skin vertex lies inside the solid
  for (int direction = 0; direction < 2; ++direction) {
    const Direction& d = directions[direction];
    const MeshModel& skin = d.skin->geometry;
    const Aabb solid_box = d.solid->geometry.bounds;
    // Signed distance at every vertex a triangle uses that can be inside the solid (inside its box).
    std::vector<Sample> at_vertex(skin.mesh.vertices.size());
    std::vector<char> evaluated(skin.mesh.vertices.size(), 0);
    for (std::size_t t = 0; t < skin.corners.size(); ++t) {
      const std::array<int, 3>& tri = skin.mesh.triangles[t];
      Piece piece;
      piece.direction = direction;
      piece.skin_triangle = int(t);
      Aabb box;
      for (int k = 0; k < 3; ++k) box.extend(d.X_SolidSkin * skin.corners[t][k]);
      const bool may_be_inside = (box.max.array() >= solid_box.min.array()).all() &&
                                 (box.min.array() <= solid_box.max.array()).all();
      if (!may_be_inside) continue;
      for (int k = 0; k < 3; ++k) {
        const int v = tri[k];
        if (!evaluated[v]) {
          at_vertex[v] = search.sample(direction, d.X_SolidSkin * skin.mesh.vertices[v]);
          evaluated[v] = 1;
        }
        piece.corner[k] = at_vertex[v];
        if (piece.corner[k].signed_distance < 0) inside_vertex[direction] = true;
      }
      if (!crossing[direction][t]) {
        // Wholly on one side of the solid's surface: skip it when outside.
        if (piece.corner[0].signed_distance > 0 || piece.corner[1].signed_distance > 0 ||
            piece.corner[2].signed_distance > 0)
          continue;
        Eigen::Vector3d center;
        smallestBall(piece.corner[0].p, piece.corner[1].p, piece.corner[2].p, center, piece.radius);
        if (search.bound(piece, nullptr)) search.push(std::move(piece));
        continue;
      }
      Eigen::Vector3d center;
      smallestBall(piece.corner[0].p, piece.corner[1].p, piece.corner[2].p, center, piece.radius);
      const Sample c = search.sample(direction, center);
      if (search.bound(piece, &c)) search.push(std::move(piece));
    }
  }
  // Pieces smaller than this are not split: the interval then stays as wide as their bounds (certified still).
  const double smallest_radius = 1e-9 * diagonal;
  const double upper = search.run(smallest_radius);

  PenetrationResult result;
  const bool surfaces_meet = !contacts.empty();
  if (!surfaces_meet) {
    // No triangle crosses: one body holds the other exactly when one of its vertices is inside the other.
    if (inside_vertex[0]) result.contained = 1;        // B's surface inside A
    else if (inside_vertex[1]) result.contained = 2;   // A's surface inside B
  }
  result.overlapping = surfaces_meet || result.contained != 0;
  if (!result.overlapping) return result;
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
  const int skin_triangle = skinTriangleOf(*d.skin, d.X_SolidSkin, s.p);
  if (direction == 0) {
    result.triangle_a = s.triangle;
    result.triangle_b = skin_triangle;
  } else {
    result.triangle_b = s.triangle;
    result.triangle_a = skin_triangle;
  }
  return result;
}

}  // namespace cfl
