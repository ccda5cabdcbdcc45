#include "calib/target_corners.h"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

namespace rangex {

std::optional<std::vector<Vec2>> find_target_corners(const uint8_t* frame, int width, int height,
                                                     int cols, int rows) {
  const cv::Mat img(height, width, CV_8UC1, const_cast<uint8_t*>(frame));
  std::vector<cv::Point2f> pts;
  const int flags = cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE;
  if (!cv::findChessboardCorners(img, cv::Size(cols, rows), pts, flags)) return std::nullopt;
  // The squares are about 15 px tall on this sensor (fy is half of fx): a 9x9 window stays
  // inside one square's neighbourhood.
  cv::cornerSubPix(img, pts, cv::Size(4, 4), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 100, 1e-4));
  std::vector<Vec2> out;
  out.reserve(pts.size());
  for (const auto& p : pts) out.push_back({p.x, p.y});
  return out;
}

}  // namespace rangex
