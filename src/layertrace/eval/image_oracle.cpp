#include "layertrace/eval/image_oracle.h"

#include <algorithm>
#include <cmath>

#include "layertrace/eval/oracle_observer.h"
#include "layertrace/screen/fragment_hit.h"

namespace lt {

namespace {

constexpr double kDepthMargin = 1e-5;   ///< relative: overlap decisions closer than this are ambiguous
/// Pixels: how far a float tracer's 2D line may lie from the true projection. Its end points
/// are projected in float, with coordinates up to a few thousand pixels (a few ulps ≈ 1e-4 px),
/// and its crossing parameters round relative to the distance travelled.
constexpr double kLineMargin = 5e-4;
constexpr double kLineRelative = 4e-6;

struct Crossing {
  double t;
  bool column;  ///< crosses x_px = const (else y_px = const)
};

}  // namespace

OracleAnswer ImageSpaceOracle::answer(const Ray& ray) const {
  OracleAnswer out;
  const double W = camera_.width(), H = camera_.height(), f = camera_.focal(), nearZ = camera_.near();
  const double ox = ray.origin.x, oy = ray.origin.y, oz = ray.origin.z;
  const double dx = ray.dir.x, dy = ray.dir.y, dz = ray.dir.z;
  auto depth = [&](double t) { return -(oz + t * dz); };
  auto px = [&](double t) { return 0.5 * W + f * (ox + t * dx) / depth(t); };
  auto py = [&](double t) { return 0.5 * H - f * (oy + t * dy) / depth(t); };
  // 1. The segment, clipped to the near plane. A ray starting behind it (at another camera's
  // eye) starts where it crosses it; one starting there or off-screen has no origin pixel.
  double tStart = 0.0, tEnd = ray.maxDistance;
  if (depth(0.0) < nearZ) {
    if (!(dz < 0.0)) return out;
    tStart = (-nearZ - oz) / dz;
  }
  if (depth(tEnd) < nearZ) tEnd = (-nearZ - oz) / dz;
  if (!(tEnd > tStart)) return out;
  const double x0 = px(tStart), y0 = py(tStart), x1 = px(tEnd), y1 = py(tEnd);
  const bool clipped = !ray.startsOnSurface || tStart > 0.0 || !(x0 >= 0.0 && x0 < W && y0 >= 0.0 && y0 < H);
  const int ox0 = clipped ? -1 : int(std::floor(x0)), oy0 = clipped ? -1 : int(std::floor(y0));

  // 2. Every crossing of a column plane x_px = X or a row plane y_px = Y, in ray order. The
  // plane x_px = X holds the eye: f·x + (X − W/2)·z = 0; likewise f·y − (Y − H/2)·z = 0.
  std::vector<Crossing> cs;
  const double xLo = std::max(0.0, std::min(x0, x1)), xHi = std::min(W, std::max(x0, x1));
  for (double X = std::ceil(xLo); X <= xHi; X += 1.0) {
    const double den = f * dx + (X - 0.5 * W) * dz;
    if (den == 0.0) continue;
    const double t = -(f * ox + (X - 0.5 * W) * oz) / den;
    if (t > tStart && t < tEnd) cs.push_back({t, true});
  }
  const double yLo = std::max(0.0, std::min(y0, y1)), yHi = std::min(H, std::max(y0, y1));
  for (double Y = std::ceil(yLo); Y <= yHi; Y += 1.0) {
    const double den = f * dy - (Y - 0.5 * H) * dz;
    if (den == 0.0) continue;
    const double t = ((Y - 0.5 * H) * oz - f * oy) / den;
    if (t > tStart && t < tEnd) cs.push_back({t, false});
  }
  std::sort(cs.begin(), cs.end(), [](const Crossing& a, const Crossing& b) { return a.t < b.t; });
  cs.push_back({tEnd, true});

  // Is [front, back] overlapping [zmin, zmax]? Flags `ambiguous` when moving the ray's range
  // by `margin` either way would change the answer.
  auto overlaps = [&](double front, double back, double zmin, double zmax, double margin) {
    const bool loose = front <= zmax + margin && back >= zmin - margin;
    const bool tight = front <= zmax - margin && back >= zmin + margin;
    if (loose != tight) out.ambiguous = true;
    return front <= zmax && back >= zmin;
  };
  const int sx = x1 > x0 ? 1 : -1, sy = y1 > y0 ? 1 : -1;
  const double lineLength = std::max(std::hypot(x1 - x0, y1 - y0), 1e-12);
  const double ux = (x1 - x0) / lineLength, uy = (y1 - y0) / lineLength;  // the 2D line's direction

  // Does pixel (ax, ay) — one a float tracer may visit where the double walk does not, or skip
  // — hold an interval within `m` of depth z? (Never the origin's own pixel.)
  auto holdsNear = [&](int ax, int ay, double z, double m) {
    if (ax < 0 || ay < 0 || ax >= int(W) || ay >= int(H) || (ax == ox0 && ay == oy0)) return false;
    const FragmentNode* fr = layers_.pixel(ax, ay);
    for (int i = 0; i < layers_.countAt(ax, ay); ++i)
      if (double(fr[i].depth) <= z + m && double(fr[i].back()) >= z - m) return true;
    return false;
  };
  // The segment's end within a float line's error of a pixel boundary: a float tracer may end
  // just before it or just past it, so it may or may not visit a sliver of the pixel across it
  // (assimp's cube.ply and box.3mf: AO rays whose end projected to 196.99999… in double, 197 in
  // float, the only interval they met in that sliver). Ambiguous when a pixel on either side
  // holds an interval within the margin of the end's depth and nothing was met before it.
  const bool endSliver = [&] {
    const double x = x1, y = y1, z = depth(tEnd);
    const double lineMargin = kLineMargin + kLineRelative * lineLength;
    const double m = kDepthMargin * z + 2.0 * std::abs(z - depth(tStart)) / lineLength * lineMargin;
    const double X = std::round(x), Y = std::round(y);
    const bool nearX = std::abs(x - X) <= lineMargin, nearY = std::abs(y - Y) <= lineMargin;
    if (!nearX && !nearY) return false;
    const int xa = nearX ? int(X) - 1 : int(std::floor(x)), xb = nearX ? int(X) : xa;
    const int ya = nearY ? int(Y) - 1 : int(std::floor(y)), yb = nearY ? int(Y) : ya;
    return holdsNear(xa, ya, z, m) || holdsNear(xb, ya, z, m) || holdsNear(xa, yb, z, m) || holdsNear(xb, yb, z, m);
  }();

  // 3. Walk the pixels between consecutive crossings.
  double tPrev = tStart;
  bool entered = false;
  for (size_t c = 0; c < cs.size(); ++c) {
    const double ta = tPrev, tb = cs[c].t;
    tPrev = tb;
    if (tb <= ta) continue;
    const double tm = 0.5 * (ta + tb);
    const double mx = px(tm), my = py(tm);
    if (!(mx >= 0.0 && mx < W && my >= 0.0 && my < H)) {
      if (entered) break;  // 4. left the viewport
      continue;            // not yet in it (a start off-screen)
    }
    entered = true;
    const int x = int(std::floor(mx)), y = int(std::floor(my));
    const double za = depth(ta), zb = depth(tb);
    const double zmin = std::min(za, zb), zmax = std::max(za, zb);
    // How far a float tracer's line may be off here, and what that does: a corner passed
    // closer than that may be cut on either side, and a pixel boundary slides along the line
    // by margin / |sin| of the line against that boundary, changing the depth range by slope ×
    // slide (capped by the pixel's own range).
    const double lineMargin = kLineMargin + kLineRelative * std::hypot(px(tb) - x0, py(tb) - y0);
    const double lenPx = std::hypot(px(tb) - px(ta), py(tb) - py(ta));
    const double slope = (zmax - zmin) / std::max(lenPx, 1e-12);
    const double slide = lineMargin / std::max(std::min(std::abs(ux), std::abs(uy)), 1e-6);
    auto margin = [&](double z) { return kDepthMargin * z + std::min(slope * slide, zmax - zmin); };
    // A corner passed within the margin: a float tracer may visit either pixel at that corner.
    if (c + 1 < cs.size() && cs[c].column != cs[c + 1].column) {
      const double tCol = cs[c].column ? cs[c].t : cs[c + 1].t, tRow = cs[c].column ? cs[c + 1].t : cs[c].t;
      const double X = std::round(px(tCol)), Y = std::round(py(tRow));
      const double distance = std::min(std::abs(px(tRow) - X), std::abs(py(tCol) - Y));
      if (distance <= lineMargin) {
        const double z = depth(cs[c].t);
        if (holdsNear(x + sx, y, z, margin(z)) || holdsNear(x, y + sy, z, margin(z))) out.ambiguous = true;
      }
    }
    if (x == ox0 && y == oy0) continue;  // the origin's own pixel (Hofmann et al. 2017, §5.1)
    const bool growing = zb >= za;
    const FragmentNode* fr = layers_.pixel(x, y);
    int best = -1;
    double bestEntry = 0.0;
    for (int i = 0; i < layers_.countAt(x, y); ++i) {
      const double front = fr[i].depth, back = fr[i].back();
      if (!overlaps(front, back, zmin, zmax, margin(zmax))) continue;
      const double entry = growing ? std::max(front, za) : std::min(back, za);
      // A near tie between an interval the ray starts the pixel inside (entry clamped to za)
      // and one it enters just after: rounding of za may swap them. Entries taken from the
      // stored data alone order the same in any precision.
      const double gap = std::abs(entry - bestEntry);
      if (best >= 0 && gap > 0.0 && gap <= margin(entry) && (entry == za || bestEntry == za)) out.ambiguous = true;
      if (best < 0 || (growing ? entry < bestEntry : entry >= bestEntry)) best = i, bestEntry = entry;
    }
    if (best >= 0) {
      out.hit = fragmentHit(camera_, layers_, x, y, best);
      if (c + 1 == cs.size() && endSliver) out.ambiguous = true;
      return out;
    }
  }
  if (endSliver) out.ambiguous = true;
  return out;
}

void OracleObserver::observe(std::span<const RayEvent> events) {
  Local& l = local_.local();
  for (const RayEvent& e : events) {
    // The origin rule of Tracer::query: past a hit on the ray's own triangle, the rest of the ray.
    OracleAnswer a = oracle_.answer(*e.ray);
    Ray next;
    for (int skip = 0; onOriginTriangle(*e.ray, a.hit); ++skip) {
      if (skip == kOriginSkips || !continuePastOrigin(*e.ray, a.hit, next)) {
        a.hit = TraceHit{};
        break;
      }
      const OracleAnswer rest = oracle_.answer(next);
      a.hit = rest.hit, a.ambiguous = a.ambiguous || rest.ambiguous;
    }
    const bool same = e.query == Query::Any ? a.hit.hit == e.hit->hit : sameFragment(a.hit, *e.hit);
    if (same) continue;
    if (a.ambiguous) ++l.ambiguous;
    else ++l.mismatches;
  }
}

uint64_t OracleObserver::mismatches() const {
  uint64_t n = 0;
  for (const Local& l : local_) n += l.mismatches;
  return n;
}

uint64_t OracleObserver::ambiguous() const {
  uint64_t n = 0;
  for (const Local& l : local_) n += l.ambiguous;
  return n;
}

}  // namespace lt
