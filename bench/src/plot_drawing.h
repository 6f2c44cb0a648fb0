#pragma once
// Drawing helpers shared by the benchmarks' plots (OpenCV).
#include <opencv2/core.hpp>
#include <string>

namespace msk::plot {

/// A "nice" tick step (1, 2 or 5 × 10^k) giving about `count` ticks over `span`.
double tickStep(double span, int count);

/// `s` drawn with its baseline starting at `at`.
void text(cv::Mat& pic, const std::string& s, cv::Point at, double scale = 0.45, cv::Scalar colour = {0, 0, 0});

}  // namespace msk::plot
