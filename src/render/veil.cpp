#include "raindrop/render/veil.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "raindrop/common/rng.h"
#include "raindrop/render/linear_frame.h"
#include "raindrop/render/srgb.h"

namespace raindrop {
namespace {

constexpr std::uint64_t kDrawStream = hash_string("veil: draw");
constexpr double kPi = 3.14159265358979323846;

// The averaging factor of the fast method: the blur runs on a grid k times coarser, with at
// least 4 of its pixels per sigma (below that the Gaussian is too narrow to sample well).
int fast_factor(double sigma_px) { return std::max(1, static_cast<int>(std::floor(sigma_px / 4.0))); }

}  // namespace

double VeilSample::scattered() const { return 1.0 - std::exp(-optical_depth); }

bool VeilSample::visible(const HighlightLift& lift) const {
  const double reach = lift.active() ? std::max(1.0, static_cast<double>(lift.gain)) : 1.0;
  return sigma_px > 0 && scattered() * reach >= kVeilSkipFraction;
}

VeilSample sample_veil(const SceneConfig& config, double fx, std::uint64_t sample_seed) {
  VeilSample v;
  if (!config.veil.enabled) return v;
  Rng rng(mix64(sample_seed ^ kDrawStream));
  v.optical_depth = rng.uniform(config.veil.optical_depth.lo, config.veil.optical_depth.hi);
  v.spread_deg = rng.uniform(config.veil.spread_deg.lo, config.veil.spread_deg.hi);
  v.sigma_px = fx * std::tan(v.spread_deg * kPi / 180.0);
  return v;
}

// Linear interpolation of `coarse` (CV_32FC3) at column positions u(x) = x0 + (x + 0.5) / r - 0.5
// for x in [0, n): the pixel centres of a full-resolution row seen on the coarse grid.
struct Lerp {
  std::vector<int> index;
  std::vector<float> weight;  // of index + 1
  Lerp(int n, double r, double x0) : index(n), weight(n) {
    for (int x = 0; x < n; ++x) {
      const double u = x0 + (x + 0.5) / r - 0.5;
      index[x] = static_cast<int>(std::floor(u));
      weight[x] = static_cast<float>(u - index[x]);
    }
  }
};

cv::Mat veil_blur(const cv::Mat& linear, double sigma_px, VeilMethod method) {
  CV_Assert(linear.type() == CV_32FC3 && sigma_px > 0);
  cv::Mat out;
  const int k = fast_factor(sigma_px);
  const int cw = std::max(1, static_cast<int>(std::lround(static_cast<double>(linear.cols) / k)));
  const int ch = std::max(1, static_cast<int>(std::lround(static_cast<double>(linear.rows) / k)));
  // A frame a few cells wide gains nothing from the coarse grid (and its mirrored margin would
  // dwarf it): the exact blur is cheap there.
  if (method == VeilMethod::Exact || k == 1 || cw < 4 || ch < 4) {
    cv::GaussianBlur(linear, out, cv::Size(0, 0), sigma_px, sigma_px, cv::BORDER_REFLECT);
    return out;
  }
  // Average the frame down to a grid about k times coarser whose cells tile it exactly (a
  // fractional ratio r = w / cw per axis; INTER_AREA weighs the cells' overlap). Mirroring about
  // the frame's edge (BORDER_REFLECT, abc|cba) then commutes with the averaging, so the coarse
  // grid mirrored by the exact kernel's reach (4 sigma, OpenCV's) is the average of the mirrored
  // frame: the surround the exact blur sees, at about 1/k^2 of the cost.
  const int w = linear.cols, h = linear.rows;
  const double rx = static_cast<double>(w) / cw, ry = static_cast<double>(h) / ch;
  cv::Mat coarse;
  cv::resize(linear, coarse, cv::Size(cw, ch), 0, 0, cv::INTER_AREA);
  const int mx = static_cast<int>(std::ceil(4 * sigma_px / rx)) + 2, my = static_cast<int>(std::ceil(4 * sigma_px / ry)) + 2;
  cv::copyMakeBorder(coarse, coarse, my, my, mx, mx, cv::BORDER_REFLECT);
  // The cell's box (variance r^2/12) and the interpolation's tent (r^2/6) add to the blur's.
  auto reduced = [&](double r) { return std::sqrt(std::max(sigma_px * sigma_px - 0.25 * r * r, 0.25 * r * r)) / r; };
  cv::GaussianBlur(coarse, coarse, cv::Size(0, 0), reduced(rx), reduced(ry), cv::BORDER_REFLECT);
  // Back to full resolution at the pixel centres: rows first (onto the coarse columns), then
  // columns. The margin keeps every sample inside the blurred grid.
  const Lerp across(w, rx, mx), down(h, ry, my);
  cv::Mat rows(h, coarse.cols, CV_32FC3);
  for (int y = 0; y < h; ++y) {
    const float* a = coarse.ptr<float>(down.index[y]);
    const float* b = coarse.ptr<float>(down.index[y] + 1);
    float* q = rows.ptr<float>(y);
    const float t = down.weight[y];
    for (int i = 0; i < 3 * coarse.cols; ++i) q[i] = a[i] + t * (b[i] - a[i]);
  }
  out.create(h, w, CV_32FC3);
  for (int y = 0; y < h; ++y) {
    const float* p = rows.ptr<float>(y);
    float* q = out.ptr<float>(y);
    for (int x = 0; x < w; ++x, q += 3) {
      const float* a = p + 3 * across.index[x];
      const float t = across.weight[x];
      q[0] = a[0] + t * (a[3] - a[0]);
      q[1] = a[1] + t * (a[4] - a[1]);
      q[2] = a[2] + t * (a[5] - a[2]);
    }
  }
  return out;
}

void apply_veil(cv::Mat& rgb, const VeilSample& veil, const HighlightLift& lift, VeilMethod method) {
  CV_Assert(rgb.type() == CV_8UC3);
  if (!veil.visible(lift) || rgb.empty()) return;
  const cv::Mat linear = lifted_linear(rgb, lift);
  const cv::Mat spread = veil_blur(linear, veil.sigma_px, method);
  const float s = static_cast<float>(veil.scattered());
  const SrgbTables& tables = SrgbTables::get();
  for (int y = 0; y < rgb.rows; ++y) {
    const auto* a = linear.ptr<float>(y);
    const auto* b = spread.ptr<float>(y);
    auto* p = rgb.ptr<unsigned char>(y);
    for (int x = 0; x < rgb.cols; ++x, a += 3, b += 3, p += 3) {
      float mixed[3] = {(1 - s) * a[0] + s * b[0], (1 - s) * a[1] + s * b[1], (1 - s) * a[2] + s * b[2]};
      lift.restore(mixed);
      p[0] = tables.encode(mixed[0]);
      p[1] = tables.encode(mixed[1]);
      p[2] = tables.encode(mixed[2]);
    }
  }
}

}  // namespace raindrop
