#pragma once
/// Inside/outside of a closed surface that stays meaningful where the surface folds or touches itself: the generalised
/// winding number (Jacobson, Kavan and Sorkine-Hornung 2013), with distant groups of triangles replaced by their
/// dipole, as in the fast winding numbers of Barill et al. 2018 (order 1 on a flat grid of clusters).
#include <Eigen/Core>
#include <vector>

#include "msk/core/triangle_mesh.h"

namespace msk {

/// Solid angle of triangle (a, b, c) seen from q, divided by 4π (Van Oosterom and Strackee 1983); in (−½, ½).
double triangleWindingNumber(const Eigen::Vector3d& q, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                             const Eigen::Vector3d& c);

/// Winding number of a closed, outward-oriented triangle surface: ≈ 1 inside, ≈ 0 outside (2 where it covers a point
/// twice). Triangles are grouped in a tree of cubic cells, each level's cells twice the size of the one below (an
/// octree); a node seen from farther than `farFactor` times its radius contributes its dipole Σ aᵢnᵢ·(c − q)/(4π|c −
/// q|³), a nearer one its children, and the nearest leaves their triangles one by one (exact).
class WindingNumber {
 public:
  /// `clusterMm` ≤ 0: twice the mean edge length. farFactor ≥ 1 (2 keeps the error far below the ½ threshold
  /// for smooth organ surfaces).
  WindingNumber(const Points& vertices, const Triangles& faces, double clusterMm = 0, double farFactor = 2.0);
  /// The winding number at q (mm).
  double at(const Eigen::Vector3d& q) const;
  /// at(q) > ½.
  bool inside(const Eigen::Vector3d& q) const { return at(q) > 0.5; }
  /// The winding number at q of the surface at positions `live` (the array the faces given to the constructor index),
  /// which may have moved since construction: the triangles summed one by one (near q) are taken at `live`, the far
  /// clusters keep their dipoles. Exact near q however far the nearby triangles moved; the far field stays right
  /// while the motion is small against the clusters' distance. Throws Error if `live` has too few rows.
  double at(const Eigen::Vector3d& q, const Points& live) const;
  /// at(q, live) > ½.
  bool inside(const Eigen::Vector3d& q, const Points& live) const { return at(q, live) > 0.5; }
  /// Exact sum over every triangle (reference for tests; O(#F)).
  double exactAt(const Eigen::Vector3d& q) const;

 private:
  /// A node of the cluster tree: a leaf holds the triangles order_[begin, end), an inner node the nodes
  /// nodes_[begin, end) of the level below (cells half as large).
  struct Node {
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();  ///< area-weighted centroid of its triangles
    Eigen::Vector3d dipole = Eigen::Vector3d::Zero();  ///< Σ area · unit normal
    double radius = 0;                                 ///< largest distance from the centre to a corner
    double area = 0;                                   ///< Σ area
    int begin = 0, end = 0;
    bool leaf = false;
  };
  /// Sum over the tree at q; `corner(t, k)` gives corner k of triangle t.
  template <class Corner>
  double sum(const Eigen::Vector3d& q, const Corner& corner) const;
  Points v_;
  Triangles f_;
  Triangles given_;    ///< the faces as given (indices into the caller's vertex array)
  int givenRows_ = 0;  ///< rows of the vertex array given to the constructor
  double far_;
  std::vector<Node> nodes_;  ///< leaves first, then each coarser level's nodes
  std::vector<int> roots_;   ///< the coarsest level's nodes
  std::vector<int> order_;
};

}  // namespace msk
