#include "layertrace/eval/verify_layers.h"

#include "layertrace/util/error.h"
#include "layertrace/util/parallel.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>

#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace lt {

float verifyDepthTolerance(float depth, glm::vec3 eye, glm::vec3 dir, glm::vec3 normal) {
  const float length = glm::length(dir), n = glm::length(normal);
  const float cosine = n > 0.0f && length > 0.0f ? std::abs(glm::dot(normal, dir)) / (n * length) : 1.0f;
  const glm::vec3 extent = glm::max(glm::abs(eye), glm::abs(eye + dir * depth));
  const float magnitude = std::max({extent.x, extent.y, extent.z});
  // Distance along the ray ε·M / cos θ, as depth (dir has unit depth component).
  const float conditioning = kVerifyConditioningEpsilons * std::numeric_limits<float>::epsilon() * magnitude /
                             (std::max(cosine, 1e-6f) * std::max(length, 1.0f));
  return kVerifyRelativeTolerance * depth + conditioning;
}

namespace {

VerifyResult verify(const FragmentLists& lists, const Camera& camera, const EmbreeScene& embree, const Scene* frontFacesOf,
                    size_t firstHits) {
  LT_CHECK(lists.head.size() == size_t(lists.width) * size_t(lists.height), lists.head.size());  // needs the list pipeline
  std::atomic<uint64_t> matching{0}, fewer{0}, more{0}, depth{0};
  const glm::vec3 eye = camera.desc().eye;
  parallelFor(tbb::blocked_range<int>(0, lists.height, 4), [&](const tbb::blocked_range<int>& r) {
    std::vector<GeoHit> hits;
    std::vector<float> frags;
    uint64_t m = 0, f = 0, mo = 0, d = 0;
    for (int y = r.begin(); y != r.end(); ++y)
      for (int x = 0; x < lists.width; ++x) {
        // Direction with unit depth component: Embree's t is then the fragment depth.
        const glm::vec3 dir = camera.dirToWorld(camera.rayThrough({float(x) + 0.5f, float(y) + 0.5f}));
        embree.allHits(eye, dir, camera.near(), camera.far(), hits);
        if (frontFacesOf) {
          const Scene& s = *frontFacesOf;
          const glm::vec3 view = camera.orthographic() ? camera.dirToWorld({0.0f, 0.0f, -1.0f}) : glm::vec3(0.0f);
          std::erase_if(hits, [&](const GeoHit& h) {
            const glm::uvec3 t = s.triangles[h.triangle];
            const glm::vec3 a = s.positions[t.x], n = glm::cross(s.positions[t.y] - a, s.positions[t.z] - a);
            return !(glm::dot(n, camera.orthographic() ? view : a - eye) < 0.0f);
          });
        }
        if (firstHits > 0 && hits.size() > firstHits) hits.resize(firstHits);
        frags.clear();
        for (uint32_t i = lists.head[lists.pixelIndex(x, y)]; i != kNullIndex; i = lists.nodes[i].next)
          frags.push_back(lists.nodes[i].depth);
        std::sort(frags.begin(), frags.end());
        if (frags.size() < hits.size()) {
          ++f;
        } else if (frags.size() > hits.size()) {
          ++mo;
        } else {
          bool ok = true;
          for (size_t i = 0; i < frags.size() && ok; ++i)
            ok = std::abs(frags[i] - hits[i].t) <= verifyDepthTolerance(hits[i].t, eye, dir, hits[i].ng);
          ok ? ++m : ++d;
        }
      }
    matching += m, fewer += f, more += mo, depth += d;
  });
  VerifyResult res;
  res.pixels = uint64_t(lists.width) * uint64_t(lists.height);
  res.matching = matching;
  res.fewerFragments = fewer;
  res.moreFragments = more;
  res.depthMismatch = depth;
  return res;
}

}  // namespace

VerifyResult verifyLayers(const FragmentLists& lists, const Camera& camera, const EmbreeScene& embree, const Scene* frontFacesOf) {
  return verify(lists, camera, embree, frontFacesOf, 0);
}

VerifyResult verifyLayerArrays(const LayerArrays& layers, const Camera& camera, const EmbreeScene& embree, const Scene* frontFacesOf) {
  // The layers as lists of at most k fragments each.
  FragmentLists lists;
  lists.width = layers.width, lists.height = layers.height;
  lists.head.assign(layers.count.size(), kNullIndex);
  lists.nodes.resize(layers.slots.size());
  for (size_t p = 0; p < layers.count.size(); ++p)
    for (int i = layers.count[p] - 1; i >= 0; --i) {
      const size_t slot = p * size_t(layers.k) + size_t(i);
      lists.nodes[slot] = layers.slots[slot];
      lists.nodes[slot].next = lists.head[p];
      lists.head[p] = uint32_t(slot);
    }
  return verify(lists, camera, embree, frontFacesOf, size_t(layers.k));
}

LayerAgreement compareLayerArrays(const LayerArrays& a, const LayerArrays& b, float relativeTolerance) {
  LT_CHECK(a.width == b.width && a.height == b.height && a.k == b.k, a.width, b.width, a.height, b.height, a.k, b.k);
  LayerAgreement r;
  r.pixelLayers = uint64_t(a.count.size()) * uint64_t(a.k);
  for (size_t p = 0; p < a.count.size(); ++p) {
    r.countsDiffer += a.count[p] != b.count[p];
    for (int i = 0; i < a.k; ++i) {
      const size_t s = p * size_t(a.k) + size_t(i);
      const bool ha = i < a.count[p], hb = i < b.count[p];
      if (!ha || !hb) {
        r.matching += ha == hb;
        continue;
      }
      ++r.filled;
      const float da = a.slots[s].depth, db = b.slots[s].depth;
      const bool match = a.triangle[s] == b.triangle[s] && std::abs(da - db) <= relativeTolerance * std::max(da, db);
      r.matching += match;
      r.sameBits += match && da == db && a.slots[s].normal == b.slots[s].normal && a.slots[s].albedoSpec == b.slots[s].albedoSpec;
    }
  }
  return r;
}

uint64_t embreeCapture(const Camera& camera, const EmbreeScene& embree) {
  std::atomic<uint64_t> total{0};
  const glm::vec3 eye = camera.desc().eye;
  parallelFor(tbb::blocked_range<int>(0, camera.height(), 4), [&](const tbb::blocked_range<int>& r) {
    std::vector<GeoHit> hits;
    uint64_t n = 0;
    for (int y = r.begin(); y != r.end(); ++y)
      for (int x = 0; x < camera.width(); ++x) {
        embree.allHits(eye, camera.dirToWorld(camera.rayThrough({float(x) + 0.5f, float(y) + 0.5f})), camera.near(), camera.far(), hits);
        n += hits.size();
      }
    total += n;
  });
  return total;
}

}  // namespace lt
