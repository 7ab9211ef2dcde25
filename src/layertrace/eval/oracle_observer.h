// Compares every observed ray's answer with an oracle's answer to the same ray
// (docs/evaluation.md: the exhaustive image-space oracle behind --check-exhaustive).
#pragma once

#include <cstdint>
#include <vector>

#include <tbb/enumerable_thread_specific.h>

#include "layertrace/render/ray_observer.h"
#include "layertrace/trace/tracer.h"

namespace lt {

/// Same answer: both miss, or both hit the same stored fragment (pixel and layer).
inline bool sameFragment(const TraceHit& a, const TraceHit& b) {
  return a.hit == b.hit && (!a.hit || (a.x == b.x && a.y == b.y && a.layer == b.layer));
}

class MismatchObserver : public RayObserver {
 public:
  explicit MismatchObserver(const Tracer& oracle) : oracle_(oracle) {}
  void observe(std::span<const RayEvent> events) override {
    Local& l = local_.local();
    l.rays.resize(events.size());
    l.answers.resize(events.size());
    for (size_t i = 0; i < events.size(); ++i) l.rays[i] = *events[i].ray;
    oracle_.query(Query::Closest, l.rays, l.answers, {});  // (the origin rule of the observed answers)
    for (size_t i = 0; i < events.size(); ++i) l.mismatches += !sameFragment(*events[i].hit, l.answers[i]);
  }
  uint64_t mismatches() const {
    uint64_t n = 0;
    for (const Local& l : local_) n += l.mismatches;
    return n;
  }

 private:
  const Tracer& oracle_;
  struct Local {
    uint64_t mismatches = 0;
    std::vector<Ray> rays;
    std::vector<TraceHit> answers;
  };
  tbb::enumerable_thread_specific<Local> local_;
};

/// Forwards every batch to several observers.
class ObserverList : public RayObserver {
 public:
  void add(RayObserver* o) {
    if (o) list_.push_back(o);
  }
  bool empty() const { return list_.empty(); }
  void observe(std::span<const RayEvent> events) override {
    for (RayObserver* o : list_) o->observe(events);
  }

 private:
  std::vector<RayObserver*> list_;
};

}  // namespace lt
