#include "msk/core/surface_separation.h"

#include <gtest/gtest.h>

#include "msk/core/error.h"
#include "msk/core/winding_number.h"

namespace {
Eigen::Vector3d momentum(const msk::TriangleMesh& m, double inverseMass) {
  return m.vertices.colwise().sum().transpose() / inverseMass;
}
int verticesInside(const msk::TriangleMesh& a, const msk::TriangleMesh& b) {
  const msk::WindingNumber wn(b.vertices, b.faces);
  int n = 0;
  for (int v = 0; v < a.vertexCount(); ++v) n += wn.exactAt(a.vertices.row(v).transpose()) > 0.5;
  return n;
}
}  // namespace

// Two spheres overlapping by 1.5 mm end apart by the gap, the heavier one moving less, with linear momentum kept.
// (Without internal constraints the surfaces dent rather than move whole, so deeper overlaps need more sweeps.)
TEST(SurfaceSeparation, PushesOverlappingSpheresApartConservingMomentum) {
  msk::TriangleMesh a = msk::makeIcosphere(10, 3, {0, 0, 0}), b = msk::makeIcosphere(10, 3, {18.5, 0, 0});
  const double wa = 0.2, wb = 1.0;  // a is five times heavier
  ASSERT_GT(verticesInside(a, b), 10);
  const Eigen::Vector3d before = momentum(a, wa) + momentum(b, wb);
  const Eigen::Vector3d ca = a.vertices.colwise().mean(), cb = b.vertices.colwise().mean();
  std::vector<msk::TriangleMesh*> s = {&a, &b};
  msk::SeparationOptions opts;
  opts.maxSweeps = 100;
  const msk::SeparationReport rep = msk::separateSurfaces(s, {wa, wb}, {{0, 1, 0.2}}, opts);
  EXPECT_TRUE(rep.clean) << rep.sweeps << " sweeps";
  EXPECT_LT(rep.sweeps, 100);
  EXPECT_GT(rep.corrections, 0);
  EXPECT_EQ(verticesInside(a, b), 0);
  EXPECT_EQ(verticesInside(b, a), 0);
  EXPECT_DOUBLE_EQ(msk::penetrationDepth(a, b), 0.0);
  EXPECT_DOUBLE_EQ(msk::penetrationDepth(b, a), 0.0);
  const Eigen::Vector3d after = momentum(a, wa) + momentum(b, wb);
  EXPECT_LT((after - before).norm(), 1e-9 * before.norm());
  // The light sphere gave way more than the heavy one.
  const double moveA = (a.vertices.colwise().mean().transpose() - ca).norm();
  const double moveB = (b.vertices.colwise().mean().transpose() - cb).norm();
  EXPECT_GT(moveB, 2 * moveA);
}

TEST(SurfaceSeparation, MeasuresPenetrationAndLeavesSeparateSurfacesAlone) {
  msk::TriangleMesh a = msk::makeIcosphere(10, 3, {0, 0, 0}), b = msk::makeIcosphere(10, 3, {19, 0, 0});
  const double depth = msk::penetrationDepth(b, a);
  EXPECT_GT(depth, 0.5);  // b's leftmost vertex is about 1 mm inside a
  EXPECT_LT(depth, 1.1);
  msk::TriangleMesh c = msk::makeIcosphere(10, 3, {30, 0, 0});
  const msk::TriangleMesh c0 = c;
  std::vector<msk::TriangleMesh*> s = {&a, &c};
  const msk::SeparationReport rep = msk::separateSurfaces(s, {1.0, 1.0}, {{0, 1, 0.2}});
  EXPECT_TRUE(rep.clean);
  EXPECT_EQ(rep.corrections, 0);
  EXPECT_EQ((c.vertices - c0.vertices).norm(), 0.0);
}

TEST(SurfaceSeparation, RejectsBadInput) {
  msk::TriangleMesh a = msk::makeIcosphere(10, 2), b = msk::makeIcosphere(10, 2, {15, 0, 0});
  std::vector<msk::TriangleMesh*> s = {&a, &b};
  EXPECT_THROW(msk::separateSurfaces(s, {1.0}, {{0, 1, 0.2}}), msk::Error);
  EXPECT_THROW(msk::separateSurfaces(s, {1.0, 1.0}, {{0, 0, 0.2}}), msk::ParameterError);
  EXPECT_THROW(msk::separateSurfaces(s, {1.0, 1.0}, {{0, 2, 0.2}}), msk::ParameterError);
  EXPECT_THROW(msk::separateSurfaces(s, {1.0, 1.0}, {{0, 1, -1}}), msk::ParameterError);
  EXPECT_THROW(msk::separateSurfaces(s, {1.0, -1.0}, {{0, 1, 0.2}}), msk::Error);
}

// Four spheres pressed into each other in a ring (each touching two others): pairs sharing no sphere run together,
// and the result is the same, bit for bit, on one, two or three threads; the check ends clean.
TEST(SurfaceSeparation, ParallelPairsGiveTheSameSurfacesForAnyThreadCount) {
  auto scene = []() {
    std::vector<msk::TriangleMesh> s;
    s.push_back(msk::makeIcosphere(10, 3, {0, 0, 0}));
    s.push_back(msk::makeIcosphere(10, 3, {18.8, 0, 0}));
    s.push_back(msk::makeIcosphere(10, 3, {18.8, 18.6, 0}));
    s.push_back(msk::makeIcosphere(10, 3, {0.3, 18.7, 0}));
    return s;
  };
  const std::vector<msk::SeparationPair> pairs = {{0, 1, 0.2}, {1, 2, 0.2}, {2, 3, 0.2}, {3, 0, 0.2}};
  std::vector<msk::Points> reference;
  for (int threads : {1, 2, 3}) {
    std::vector<msk::TriangleMesh> s = scene();
    std::vector<msk::TriangleMesh*> ptr;
    for (msk::TriangleMesh& m : s) ptr.push_back(&m);
    msk::SeparationOptions opts;
    opts.maxSweeps = 100;
    opts.threads = threads;
    const msk::SeparationReport rep = msk::separateSurfaces(ptr, {1.0, 0.5, 1.0, 0.5}, pairs, opts);
    EXPECT_TRUE(rep.clean) << threads << " threads";
    for (const msk::SeparationPair& p : pairs) {
      EXPECT_EQ(verticesInside(s[static_cast<size_t>(p.a)], s[static_cast<size_t>(p.b)]), 0);
      EXPECT_EQ(verticesInside(s[static_cast<size_t>(p.b)], s[static_cast<size_t>(p.a)]), 0);
    }
    for (size_t i = 0; i < s.size(); ++i) {
      if (threads == 1) {
        reference.push_back(s[i].vertices);
      } else {
        EXPECT_EQ((s[i].vertices - reference[i]).norm(), 0.0) << "sphere " << i << " on " << threads << " threads";
      }
    }
  }
  std::vector<msk::TriangleMesh> s = scene();
  std::vector<msk::TriangleMesh*> ptr = {&s[0], &s[1]};
  msk::SeparationOptions bad;
  bad.threads = -1;
  EXPECT_THROW(msk::separateSurfaces(ptr, {1.0, 1.0}, {{0, 1, 0.2}}, bad), msk::ParameterError);
}

// A second run given the first run's memory, with the move made in between declared, ends with the surfaces of a run
// without it (what the memory skips could not have needed a correction) and skips more samples; an undeclared move
// that pushes one surface into the other is missed by the skipped samples, which is why moves are declared.
TEST(SurfaceSeparation, AMemoryOfTheLastRunSkipsSamplesAndChangesNothing) {
  auto spheres = [] {
    return std::pair<msk::TriangleMesh, msk::TriangleMesh>{msk::makeIcosphere(10, 4, {0, 0, 0}),
                                                           msk::makeIcosphere(10, 4, {19.0, 0, 0})};
  };
  msk::SeparationOptions opts;
  opts.maxSweeps = 100;
  opts.reachMm = 4.0;
  auto [a, b] = spheres();
  std::vector<msk::TriangleMesh*> s = {&a, &b};
  msk::SeparationMemory memory;
  ASSERT_TRUE(msk::separateSurfaces(s, {1.0, 1.0}, {{0, 1, 0.2}}, opts, &memory).clean);
  // Then b moves 1.5 mm towards a, into it.
  b.vertices.col(0).array() -= 1.5;
  msk::TriangleMesh a2 = a, b2 = b;
  std::vector<msk::TriangleMesh*> s2 = {&a2, &b2};
  const msk::SeparationReport fresh = msk::separateSurfaces(s2, {1.0, 1.0}, {{0, 1, 0.2}}, opts);
  msk::TriangleMesh a3 = a, b3 = b;
  std::vector<msk::TriangleMesh*> s3 = {&a3, &b3};
  memory.moved(1, 1.5);
  const msk::SeparationReport remembered = msk::separateSurfaces(s3, {1.0, 1.0}, {{0, 1, 0.2}}, opts, &memory);
  EXPECT_TRUE(remembered.clean);
  EXPECT_GT(remembered.skipped, fresh.skipped);
  EXPECT_EQ(remembered.corrections, fresh.corrections);
  EXPECT_EQ((a3.vertices - a2.vertices).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ((b3.vertices - b2.vertices).cwiseAbs().maxCoeff(), 0.0);
  // The same memory without the move declared: samples now inside are skipped as if still outside.
  auto [a4, b4] = spheres();
  std::vector<msk::TriangleMesh*> s4 = {&a4, &b4};
  msk::SeparationMemory undeclared;
  ASSERT_TRUE(msk::separateSurfaces(s4, {1.0, 1.0}, {{0, 1, 0.2}}, opts, &undeclared).clean);
  b4.vertices.col(0).array() -= 1.5;
  msk::separateSurfaces(s4, {1.0, 1.0}, {{0, 1, 0.2}}, opts, &undeclared);
  EXPECT_NE((b4.vertices - b2.vertices).cwiseAbs().maxCoeff(), 0.0);
}
