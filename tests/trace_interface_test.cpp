// The tracing core (trace/): every tracer's batch paths answer exactly as its one-ray reference
// path, counted or not; effects report every traced ray to an observer without changing the
// image; and the source tree keeps the layering of docs/architecture.md.
#include <bit>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <mutex>
#include <random>

#include "layertrace/pipeline/tracer_registry.h"
#include "layertrace/render/effects.h"
#include "layertrace/util/error.h"
#include "test_util.h"

namespace lt {
namespace {

Frame defaultFrame(int w = 160, int h = 90) {
  FrameOptions o;
  o.scenePath = test::sourceDir() + "/scenes/default.json";
  o.width = w, o.height = h;
  return buildFrame(o);
}

/// Bitwise equality of everything a hit carries.
::testing::AssertionResult sameHit(const TraceHit& a, const TraceHit& b) {
  if (a.hit != b.hit) return ::testing::AssertionFailure() << "hit " << a.hit << " vs " << b.hit;
  if (!a.hit) return ::testing::AssertionSuccess();
  if (a.x != b.x || a.y != b.y || a.layer != b.layer || a.triangle != b.triangle || a.albedoSpec != b.albedoSpec ||
      std::memcmp(&a.point, &b.point, sizeof a.point) != 0 || std::memcmp(&a.normal, &b.normal, sizeof a.normal) != 0)
    return ::testing::AssertionFailure() << "pixel " << a.x << "," << a.y << " layer " << a.layer << " triangle " << a.triangle
                                         << " vs pixel " << b.x << "," << b.y << " layer " << b.layer << " triangle " << b.triangle;
  return ::testing::AssertionSuccess();
}

const char* const kTracers[] = {"ssr", "ssr-layers", "hiz", "hssr", "quadtree", "ldc", "hybrid", "embree", "grid"};

TEST(TraceInterface, BatchPathsAnswerAsTheOneRayPathBitForBit) {
  const Frame f = defaultFrame();
  const std::vector<Ray> rays = test::sampleRays(f, 3000, test::testSeed());
  TracerOptions options;
  options.ldc.resolution = 256;  // the paths, not the capture, are under test (fast under ASan)
  for (const char* name : kTracers) {
    SCOPED_TRACE(name);
    const BuiltTracer b = buildTracer(name, f, options);
    std::vector<TraceHit> uncounted(rays.size()), counted(rays.size()), any(rays.size());
    std::vector<RayCounters> counters(rays.size());
    b.tracer->traceBatch(rays, uncounted, {});
    b.tracer->traceBatch(rays, counted, counters);
    b.tracer->occludedBatch(rays, any, {});
    uint64_t hits = 0, iterations = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
      RayCounters c;
      const TraceHit one = b.tracer->trace(rays[i], c);
      hits += one.hit;
      ASSERT_TRUE(sameHit(one, uncounted[i])) << "ray " << i << " (seed " << test::testSeed() << ")";
      ASSERT_TRUE(sameHit(one, counted[i])) << "ray " << i;
      ASSERT_EQ(one.hit, any[i].hit) << "any-hit answer of ray " << i;
      ASSERT_EQ(c.iterations, counters[i].iterations) << "ray " << i;
      ASSERT_EQ(c.intervals, counters[i].intervals) << "ray " << i;
      iterations += c.iterations;
    }
    EXPECT_GT(hits, rays.size() / 4) << "too few hits for the comparison to mean anything";
    if (kCountersCompiled) {
      EXPECT_GE(iterations, rays.size() / 2) << "the counted path counted nothing";
    }
  }
}

// Plain Embree in 16-wide packets (compare's packet baseline) answers the same rays
// as one rtcIntersect1 per ray, batches of any length (partial packets) included.
TEST(TraceInterface, EmbreePacketsAnswerAsSingleRays) {
  const Frame f = defaultFrame();
  std::vector<Ray> rays = test::sampleRays(f, 3000, test::testSeed() + 1);
  for (size_t i = 0; i < rays.size(); i += 3) rays[i].maxDistance *= 0.05f;  // each ray its own tfar
  // Plain Embree (the hybrid's default geometric half) and robust Embree (--hybrid-geo
  // embree-robust) alike.
  for (const bool robust : {false, true}) {
    SCOPED_TRACE(robust ? "robust" : "plain");
    const BuiltTracer single = robust ? buildReference(f) : buildTracer("embree", f, TracerOptions{});
    const EmbreePacketTracer packets(f.scene, f.camera, *single.embree);
    std::vector<TraceHit> batch(rays.size());
    for (size_t b = 0; b < rays.size(); b += 37) {
      const size_t n = std::min<size_t>(37, rays.size() - b);
      packets.traceBatch(std::span<const Ray>(&rays[b], n), std::span<TraceHit>(&batch[b], n), {});
    }
    std::vector<TraceHit> blocked(rays.size());
    for (size_t b = 0; b < rays.size(); b += 37) {
      const size_t n = std::min<size_t>(37, rays.size() - b);
      packets.occludedBatch(std::span<const Ray>(&rays[b], n), std::span<TraceHit>(&blocked[b], n), {});
    }
    std::vector<TraceHit> anyOne(rays.size());
    std::vector<RayCounters> counters(rays.size());
    single.tracer->occludedBatch(rays, anyOne, counters);  // counted: rtcOccluded1 per ray
    size_t hits = 0, differ = 0, differAny = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
      RayCounters c;
      const TraceHit one = single.tracer->trace(rays[i], c), any = anyOne[i];
      hits += one.hit;
      differ += !sameHit(one, batch[i]);
      differAny += !sameHit(any, blocked[i]);
    }
    EXPECT_GT(hits, rays.size() / 4);
    EXPECT_LT(hits, rays.size() - rays.size() / 10) << "the short rays should miss";
    EXPECT_EQ(differ, 0u) << "of " << rays.size() << " rays (closest hit)";
    EXPECT_EQ(differAny, 0u) << "of " << rays.size() << " rays (any hit)";
  }
}

// The geometric tracers' segment queries (GeoHitQueries, the hybrid's geometric half). Whole rays
// (no `from`): makeHit of each bare hit is the one-ray answer bit for bit, counted or not, in
// batches of any length, and the counted path counts as the one-ray path does. Segments started
// at from[i] are the whole ray started later: where its hit lies at or past from[i], the segment
// finds that hit bit for bit — from 0, from just before the hit (within the 1e-4 relative origin
// offset a ray moved to from[i] skips; and 10⁻⁷ of the hit's distance before it,
// within the rounding of plain Embree's tests), from exactly the hit, from anywhere before it —
// and where it lies before from[i], the segment's hit lies at most the slack before from[i].
// Any hits are the closest hits' verdicts.
TEST(TraceInterface, GeoSegmentsAreTheWholeRaysHits) {
  const Frame f = defaultFrame();
  std::vector<Ray> rays = test::sampleRays(f, 3000, test::testSeed() + 2);
  for (size_t i = 0; i < rays.size(); i += 3) rays[i].maxDistance *= 0.05f;
  const BuiltTracer embree = buildTracer("embree", f, TracerOptions{});
  const BuiltTracer grid = buildTracer("grid", f, TracerOptions{});
  const EmbreePacketTracer packets(f.scene, f.camera, *embree.embree);
  const GeometricHits made(f.scene, f.camera);
  // Queries in batches of 37 (partial packets and chunks).
  const auto batches = [&](auto&& query, bool counted, std::vector<RayCounters>& c) {
    c.assign(counted ? rays.size() : 0, RayCounters{});
    for (size_t b = 0; b < rays.size(); b += 37) {
      const size_t n = std::min<size_t>(37, rays.size() - b);
      query(b, n, counted ? std::span<RayCounters>(&c[b], n) : std::span<RayCounters>());
    }
  };
  for (const Tracer* t : std::initializer_list<const Tracer*>{embree.tracer.get(), grid.tracer.get(), &packets}) {
    SCOPED_TRACE(t->name());
    const auto* geo = dynamic_cast<const GeoHitQueries*>(t);
    ASSERT_NE(geo, nullptr);
    std::vector<GeoHit> whole(rays.size());
    std::vector<RayCounters> c;
    for (const bool counted : {false, true}) {
      batches([&](size_t b, size_t n, std::span<RayCounters> cs) {
        geo->intersectSegments(std::span<const Ray>(&rays[b], n), {}, std::span<GeoHit>(&whole[b], n), cs);
      }, counted, c);
      size_t hits = 0, differ = 0, countsDiffer = 0;
      for (size_t i = 0; i < rays.size(); ++i) {
        RayCounters one;
        const TraceHit h = t->trace(rays[i], one);
        hits += h.hit;
        differ += !sameHit(h, made.makeHit(rays[i], whole[i]));
        if (counted && kCountersCompiled) countsDiffer += one.iterations != c[i].iterations || one.giveUps != c[i].giveUps;
      }
      EXPECT_GT(hits, rays.size() / 4);
      EXPECT_EQ(differ, 0u) << "of " << rays.size() << " rays, counted " << counted;
      EXPECT_EQ(countsDiffer, 0u) << "of " << rays.size() << " rays";
    }
    std::mt19937_64 rng(test::testSeed());
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    std::vector<float> from(rays.size());
    for (size_t i = 0; i < rays.size(); ++i) {
      const float end = whole[i].hit() ? whole[i].t : rays[i].maxDistance;
      const float before[] = {0.0f, end * (1.0f - 2e-5f), end * u(rng), end * (1.0f + 1e-5f), end, end * (1.0f - 1e-7f)};
      from[i] = before[i % 6];
    }
    for (const bool counted : {false, true}) {
      std::vector<GeoHit> seg(rays.size());
      std::vector<uint8_t> blocked(rays.size());
      batches([&](size_t b, size_t n, std::span<RayCounters> cs) {
        geo->intersectSegments(std::span<const Ray>(&rays[b], n), std::span<const float>(&from[b], n), std::span<GeoHit>(&seg[b], n), cs);
      }, counted, c);
      batches([&](size_t b, size_t n, std::span<RayCounters> cs) {
        geo->occludedSegments(std::span<const Ray>(&rays[b], n), std::span<const float>(&from[b], n),
                              std::span<uint8_t>(&blocked[b], n), cs);
      }, counted, c);
      size_t kept = 0, justBefore = 0, differ = 0, early = 0, anyDiffer = 0;
      for (size_t i = 0; i < rays.size(); ++i) {
        const float offset = made.originOffset(rays[i]);
        if (whole[i].hit() && whole[i].t >= from[i] && whole[i].t > offset) {
          ++kept;
          justBefore += i % 6 == 1 || i % 6 == 4 || i % 6 == 5;
          differ += seg[i].triangle != whole[i].triangle || std::bit_cast<uint32_t>(seg[i].t) != std::bit_cast<uint32_t>(whole[i].t);
        } else {
          const float slack = GeoHitQueries::segmentSlack(f.camera.toWorld(rays[i].origin), from[i]);
          early += seg[i].hit() && !(seg[i].t >= std::min(from[i] - slack, offset));
        }
        anyDiffer += (blocked[i] != 0) != seg[i].hit();
      }
      EXPECT_GT(justBefore, rays.size() / 20) << "too few segments start just before their hit";
      EXPECT_EQ(differ, 0u) << "of " << kept << " segments holding the whole ray's hit, counted " << counted;
      EXPECT_EQ(early, 0u);
      EXPECT_EQ(anyDiffer, 0u) << "of " << rays.size() << " segments, counted " << counted;
    }
  }
}

/// Records every event, and re-traces its ray with the one-ray path to check the answer.
class RecordingObserver : public RayObserver {
 public:
  explicit RecordingObserver(const Tracer& t) : tracer_(t) {}
  void observe(std::span<const RayEvent> events) override {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const RayEvent& e : events) {
      TraceHit one;  // (one ray through query: the origin rule the renderer's answers follow)
      tracer_.query(Query::Closest, std::span<const Ray>(e.ray, 1), std::span<TraceHit>(&one, 1), {});
      // Any-hit answers carry only the verdict (trace/tracer.h).
      same += (e.query == Query::Any ? one.hit == e.hit->hit : bool(sameHit(one, *e.hit))) ? 1 : 0;
      ++count;
      ++perBounce[e.bounce];
      maxSample = std::max(maxSample, e.sample);
    }
  }
  uint64_t count = 0, same = 0;
  int maxSample = 0;
  std::map<int, uint64_t> perBounce;

 private:
  const Tracer& tracer_;
  std::mutex mutex_;
};

TEST(TraceInterface, ObserverSeesEveryRayAndChangesNothing) {
  const Frame f = defaultFrame();
  for (const char* name : {"hssr", "embree"}) {
    SCOPED_TRACE(name);
    const BuiltTracer b = buildTracer(name, f, TracerOptions{});
    for (Effect effect : {Effect::Reflection, Effect::AO, Effect::Refraction}) {
      SCOPED_TRACE(effectName(effect));
      EffectConfig ec;
      ec.effect = effect;
      ec.bounces = 2;
      ec.aoSamples = 3;
      RecordingObserver rec(*b.tracer);
      const EffectResult watched = renderEffect(f, *b.tracer, ec, &rec);
      const EffectResult plain = renderEffect(f, *b.tracer, ec);
      ec.countRays = false;
      const EffectResult uncounted = renderEffect(f, *b.tracer, ec);
      EXPECT_EQ(watched.image.data, plain.image.data);
      EXPECT_EQ(uncounted.image.data, plain.image.data);
      EXPECT_EQ(rec.count, watched.rays);
      EXPECT_EQ(rec.same, rec.count) << "an event carried another answer than the tracer gives its ray";
      EXPECT_EQ(uncounted.rays, plain.rays);
      EXPECT_EQ(uncounted.iterationSum, 0u);
      if (kCountersCompiled) {
        EXPECT_GT(plain.iterationSum, plain.rays / 2);
      }
      if (effect == Effect::Reflection) {
        EXPECT_EQ(rec.perBounce.size(), 2u) << "two bounces, two waves";
      }
      if (effect == Effect::AO) {
        EXPECT_EQ(rec.maxSample, 2);
      }
      EXPECT_GT(watched.traceMs, 0.0) << "the time inside the tracer calls was not measured";
    }
  }
}

/// Counts the batches it is handed with and without counters, answering with `inner`.
class CounterSpy : public Tracer {
 public:
  explicit CounterSpy(const Tracer& inner) : inner_(inner) {}
  const char* name() const override { return inner_.name(); }
  TraceHit trace(const Ray& ray, RayCounters& c) const override { return inner_.trace(ray, c); }
  void traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const override {
    std::lock_guard<std::mutex> lock(m_);
    (counters.empty() ? uncounted : counted) += rays.size();
    inner_.traceBatch(rays, hits, counters);
  }
  mutable size_t counted = 0, uncounted = 0;

 private:
  const Tracer& inner_;
  mutable std::mutex m_;
};

// Every command times the same way: measureTrace's passes hand the tracer no counters (the path
// the vector marches serve) and the tracer sees exactly the rays of the counted pass, `repeat` times.
TEST(TraceInterface, TimedPassesTraceTheSameRaysWithoutCounters) {
  const Frame f = defaultFrame();
  const BuiltTracer b = buildTracer("hssr", f, TracerOptions{});
  const CounterSpy spy(*b.tracer);
  EffectConfig ec;
  ec.effect = Effect::Reflection;
  ec.bounces = 2;
  const EffectResult counted = renderEffect(f, spy, ec);
  const size_t traced = spy.counted;  // the rays, and their continuations past their own triangle
  EXPECT_GE(traced, counted.rays);
  EXPECT_EQ(spy.uncounted, 0u);
  const TraceTiming t = measureTrace(f, spy, ec, 3);
  EXPECT_EQ(spy.counted, traced) << "a timed pass asked for counters";
  EXPECT_EQ(spy.uncounted, 3 * traced);
  EXPECT_GT(t.traceMs, 0.0);
  EXPECT_THROW(measureTrace(f, spy, ec, 0), InputError);
}

// docs/architecture.md: a layer includes only layers below it; screen/ and geometry/ never
// include each other.
TEST(TraceInterface, SourceTreeKeepsTheLayering) {
  // docs/architecture.md: a folder includes only folders of a lower rank. Folders of one rank are
  // siblings and never include each other (ssr/ and hssr/, geometry/ and screen/).
  const std::map<std::string, int> rank = {
      {"util", 0},     {"scene", 1},    {"raster", 2}, {"trace", 3},  {"screen", 4}, {"geometry", 4}, {"ssr", 5},
      {"hssr", 5},     {"quadtree", 5}, {"ldc", 5},    {"grid", 5},   {"hiz", 6},    {"hybrid", 7},   {"gpu", 8},      {"pipeline", 9},
      {"render", 10},  {"eval", 11},    {"api", 12},   {"app", 13}};
  // Image space answers from stored fragments only; geometry answers from triangles only. gpu/
  // holds the GPU twins of both kinds and of the hybrid (above both, and above hybrid/, which
  // composes both).
  const std::set<std::string> imageSpace = {"screen", "ssr", "hssr", "hiz", "quadtree", "ldc"}, geometric = {"geometry", "grid"};
  const std::string include = "#include \"layertrace/";
  const std::filesystem::path root = std::filesystem::path(test::sourceDir()) / "src/layertrace";
  size_t files = 0;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(root)) {
    if (!entry.is_regular_file()) continue;
    const std::string layer = entry.path().parent_path().filename().string();
    ASSERT_TRUE(rank.count(layer)) << "folder " << layer << " is not a layer of docs/architecture.md";
    std::ifstream in(entry.path());
    std::string line;
    ++files;
    while (std::getline(in, line)) {
      const size_t at = line.find(include);
      if (at == std::string::npos) continue;
      const size_t begin = at + include.size(), slash = line.find('/', begin);
      if (slash == std::string::npos) continue;
      const std::string to = line.substr(begin, slash - begin);
      ASSERT_TRUE(rank.count(to)) << entry.path() << " includes unknown layer " << to;
      if (to == layer) continue;
      EXPECT_FALSE(imageSpace.count(layer) && geometric.count(to)) << entry.path() << " (image space) includes " << to;
      EXPECT_FALSE(geometric.count(layer) && imageSpace.count(to)) << entry.path() << " (geometric) includes " << to;
      EXPECT_LT(rank.at(to), rank.at(layer)) << entry.path() << " (" << layer << ") includes " << to << ": " << line;
    }
  }
  EXPECT_GT(files, 40u);
}

}  // namespace
}  // namespace lt
