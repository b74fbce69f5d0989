#include "treestereo/overlay.hpp"

#include "treestereo/errors.hpp"
#include "treestereo/stats.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace treestereo {

namespace {

constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;

cv::Scalar to_scalar(Rgb c, const ChannelOrder &o)
{
  cv::Scalar s(255, 255, 255, 255); // padding / alpha channels: opaque
  s[o.r] = c.r;
  s[o.g] = c.g;
  s[o.b] = c.b;
  return s;
}

bool known_depth(double z) { return std::isfinite(z) && z > 0; }

// Colour-map range (near, far) in metres: the style's, or the data's 5th..95th percentile.
std::pair<double, double> depth_range(const OverlayScene &scene, const OverlayStyle &style)
{
  if (style.depth_far_m > style.depth_near_m && style.depth_near_m >= 0)
    return {style.depth_near_m, style.depth_far_m};
  std::vector<double> z;
  for (double d : scene.match_depth_m)
    if (known_depth(d))
      z.push_back(d);
  if (z.empty())
    for (const Band &b : scene.bands)
      if (b.present && known_depth(b.depth_m))
        z.push_back(b.depth_m);
  if (z.empty())
    return {0, 0};
  const Summary s = summarize(z);
  double near = s.p05, far = s.p95;
  // A flat scene still needs a range to map into: 10 cm around its middle.
  if (far - near < 0.1) {
    const double mid = 0.5 * (near + far);
    near = mid - 0.05;
    far = mid + 0.05;
  }
  return {near, far};
}

struct Painter {
  cv::Mat &image;
  const ChannelOrder &order;
  OverlayScale scale;
  int view_width;
  std::pair<double, double> range;

  cv::Scalar color(Rgb c) const { return to_scalar(c, order); }
  cv::Scalar depth(double z) const
  {
    if (!known_depth(z) || !(range.second > range.first))
      return color(kUnknownDepthColor);
    return color(depth_color((z - range.first) / (range.second - range.first)));
  }
  cv::Mat view(int v) const
  {
    return image(cv::Rect(v * view_width, 0, view_width, image.rows));
  }
  // White text with a dark rim, readable on any background.
  void text(const std::string &s, cv::Point org, double font) const
  {
    const int t = std::max(1, int(std::lround(font * 2)));
    cv::putText(image, s, org, kFont, font, color({0, 0, 0}), t + 2, cv::LINE_AA);
    cv::putText(image, s, org, kFont, font, color(kTextColor), t, cv::LINE_AA);
  }
};

void draw_rejected(const Painter &p, const cv::Mat &rejected)
{
  cv::Mat left = p.view(LEFT);
  if (rejected.size() != left.size() || rejected.type() != CV_8UC1)
    throw std::runtime_error("overlay: the rejected-vegetation mask must be CV_8U of the view "
                             "size " + std::to_string(left.cols) + "x" +
                             std::to_string(left.rows) + ", got " +
                             std::to_string(rejected.cols) + "x" + std::to_string(rejected.rows));
  const int n = p.order.channels;
  const int ch[3] = {p.order.r, p.order.g, p.order.b};
  const int tint[3] = {kRejectedColor.r, kRejectedColor.g, kRejectedColor.b};
  for (int y = 0; y < left.rows; ++y) {
    const uchar *m = rejected.ptr<uchar>(y);
    uchar *px = left.ptr<uchar>(y);
    for (int x = 0; x < left.cols; ++x) {
      if (!m[x])
        continue;
      uchar *q = px + std::size_t(x) * std::size_t(n);
      for (int c = 0; c < 3; ++c)
        q[ch[c]] = uchar((q[ch[c]] + tint[c] + 1) / 2);
    }
  }
}

void draw_silhouettes(const Painter &p, const OverlayScene &scene, const OverlayStyle &style)
{
  for (int v = 0; v < scene.n_views; ++v) {
    const Silhouette &s = scene.views[v];
    if (!s.present)
      continue;
    cv::Mat view = p.view(v);
    if (style.box && s.bbox.area() > 0)
      cv::rectangle(view, s.bbox, p.color(kBoxColor), p.scale.line, cv::LINE_8);
    if (style.contour && s.contour.size() >= 2)
      cv::polylines(view, s.contour, true, p.color(kContourColor), p.scale.line, cv::LINE_8);
  }
}

void draw_dot(const cv::Mat &view, cv::Point2f at, const cv::Scalar &c, const Painter &p)
{
  const cv::Point centre(int(std::lround(at.x)), int(std::lround(at.y)));
  const int rim = std::max(1, p.scale.line / 2);
  cv::circle(view, centre, p.scale.dot + rim, p.color({0, 0, 0}), cv::FILLED, cv::LINE_8);
  cv::circle(view, centre, p.scale.dot, c, cv::FILLED, cv::LINE_8);
}

void draw_matches(const Painter &p, const OverlayScene &scene, const OverlayStyle &style)
{
  const bool have_depth = scene.match_depth_m.size() == scene.matches.size();
  for (std::size_t i = 0; i < scene.matches.size(); ++i) {
    const StereoMatch &m = scene.matches[i];
    const cv::Scalar c = p.depth(have_depth ? scene.match_depth_m[i] : 0.0);
    if (style.match_style == MatchStyle::kDots) {
      draw_dot(p.view(LEFT), {m.xl, m.yl}, c, p);
      if (scene.n_views == 2)
        draw_dot(p.view(RIGHT), {m.xr, m.yr}, c, p);
      continue;
    }
    // Lines: with both views, left point to right point across the halves; with the left view
    // alone, the disparity vector (left point to where the right view saw it).
    const float off = scene.n_views == 2 ? float(p.view_width) : 0.0f;
    const cv::Point a(int(std::lround(m.xl)), int(std::lround(m.yl)));
    const cv::Point b(int(std::lround(m.xr + off)), int(std::lround(m.yr)));
    cv::line(scene.n_views == 2 ? p.image : p.view(LEFT), a, b, c, std::max(1, p.scale.line / 2),
             cv::LINE_8);
  }
}

void draw_bands(const Painter &p, const OverlayScene &scene)
{
  if (!scene.geometry.valid() || !known_depth(scene.band_depth_m))
    return;
  cv::Mat left = p.view(LEFT);
  for (const Band &b : scene.bands) {
    if (!b.present)
      continue;
    const BandSegment s = band_segment(b, scene.geometry, scene.band_depth_m);
    const cv::Scalar c = p.depth(b.depth_m);
    const int xl = int(std::lround(s.x_left)), xr = int(std::lround(s.x_right));
    const int yt = int(std::lround(s.y_top)), yb = int(std::lround(s.y_bottom));
    const int ym = int(std::lround(0.5 * (s.y_top + s.y_bottom)));
    const int t = p.scale.line + 1;
    cv::line(left, {xl, ym}, {xr, ym}, c, t, cv::LINE_8);
    cv::line(left, {xl, yt}, {xl, yb}, c, t, cv::LINE_8);
    cv::line(left, {xr, yt}, {xr, yb}, c, t, cv::LINE_8);
    char label[32];
    std::snprintf(label, sizeof label, "%.2f m", b.width_m);
    p.text(label, {xr + 2 * t, ym + int(std::lround(4 * p.scale.unit))}, 0.7 * p.scale.font);
  }
}

// The panel at a top corner of the left view: the text lines, then the depth legend. The top
// left, unless the tree in front (the left silhouette's box) is there and the top right covers
// less of it: a tree at the view's left edge keeps its crown in sight.
void draw_panel(const Painter &p, const OverlayScene &scene, bool legend)
{
  const OverlayScale &sc = p.scale;
  int baseline = 0;
  const cv::Size glyph = cv::getTextSize("Mg", kFont, sc.font, sc.font_thickness, &baseline);
  const int line_h = glyph.height + baseline + int(std::lround(4 * sc.unit));
  const int pad = int(std::lround(6 * sc.unit));
  int width = 0;
  for (const std::string &s : scene.text)
    width = std::max(width, cv::getTextSize(s, kFont, sc.font, sc.font_thickness, &baseline).width);
  char near_label[32] = "", far_label[32] = "";
  if (legend) {
    std::snprintf(near_label, sizeof near_label, "near %.2f m", p.range.first);
    std::snprintf(far_label, sizeof far_label, "far %.2f m", p.range.second);
    const int labels = cv::getTextSize(near_label, kFont, sc.font, sc.font_thickness, &baseline).width +
                       cv::getTextSize(far_label, kFont, sc.font, sc.font_thickness, &baseline).width;
    width = std::max(width, labels + 2 * pad);
  }
  const int rows = int(scene.text.size()) + (legend ? 2 : 0);
  const cv::Rect view(0, 0, p.view_width, p.image.rows);
  const cv::Size size(width + 2 * pad, rows * line_h + 2 * pad);
  cv::Rect panel = cv::Rect({pad, pad}, size) & view;
  const Silhouette &front = scene.views[LEFT];
  if (front.present && front.bbox.area() > 0) {
    const cv::Rect right = cv::Rect({p.view_width - pad - size.width, pad}, size) & view;
    if ((right & front.bbox).area() < (panel & front.bbox).area())
      panel = right;
  }
  if (panel.area() == 0)
    return;
  // Darken the colour channels only: an alpha channel stays as it was.
  cv::Scalar dim(1, 1, 1, 1);
  dim[p.order.r] = dim[p.order.g] = dim[p.order.b] = 0.3;
  cv::Mat roi = p.image(panel);
  cv::multiply(roi, dim, roi);

  int y = panel.y + pad + glyph.height;
  for (const std::string &s : scene.text) {
    cv::putText(p.image, s, {panel.x + pad, y}, kFont, sc.font, p.color(kTextColor),
                sc.font_thickness, cv::LINE_AA);
    y += line_h;
  }
  if (!legend)
    return;
  const int bar_x = panel.x + pad, bar_w = width, bar_h = std::max(2, glyph.height);
  const int bar_y = y - glyph.height;
  for (int i = 0; i < bar_w; ++i) {
    const cv::Scalar c = p.color(depth_color(double(i) / std::max(1, bar_w - 1)));
    cv::line(p.image, {bar_x + i, bar_y}, {bar_x + i, bar_y + bar_h - 1}, c, 1, cv::LINE_8);
  }
  y += line_h;
  cv::putText(p.image, near_label, {bar_x, y}, kFont, sc.font, p.color(kTextColor),
              sc.font_thickness, cv::LINE_AA);
  const int far_w = cv::getTextSize(far_label, kFont, sc.font, sc.font_thickness, &baseline).width;
  cv::putText(p.image, far_label, {bar_x + bar_w - far_w, y}, kFont, sc.font, p.color(kTextColor),
              sc.font_thickness, cv::LINE_AA);
}

std::string metres(double v)
{
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f", v);
  return buf;
}

std::string figure_line(const char *name, double value, const double *smoothed, bool lower_bound)
{
  std::string s = std::string(name) + (lower_bound ? " >= " : " ") + metres(value) + " m";
  if (smoothed && metres(*smoothed) != metres(value))
    s += " (smoothed " + metres(*smoothed) + ")";
  return s;
}

} // namespace

Rgb depth_color(double t)
{
  t = std::isfinite(t) ? std::clamp(t, 0.0, 1.0) : 0.0;
  // Hue from 360 (red) down to 220 (blue) through magenta (300) and blue (240), full value and
  // saturation: the HSV sectors written out.
  const double deg = 360.0 - 140.0 * t;
  const auto u = [](double v) { return static_cast<unsigned char>(std::lround(255.0 * v)); };
  if (deg > 300.0)
    return {255, 0, u((360.0 - deg) / 60.0)};
  if (deg > 240.0)
    return {u((deg - 240.0) / 60.0), 0, 255};
  return {0, u((240.0 - deg) / 60.0), 255};
}

OverlayScale overlay_scale(cv::Size view)
{
  OverlayScale s;
  s.unit = std::max(0.25, std::max(view.width, view.height) / 640.0);
  s.line = std::max(1, int(std::lround(1.5 * s.unit)));
  s.dot = std::max(2, int(std::lround(2.5 * s.unit)));
  s.font = std::max(0.35, 0.5 * s.unit);
  s.font_thickness = std::max(1, int(std::lround(s.unit)));
  return s;
}

BandSegment band_segment(const Band &band, const StereoGeometry &g, double depth_m)
{
  require_valid(g, "placing the bands", "band_segment");
  if (!known_depth(depth_m))
    throw std::runtime_error("overlay: band projection depth must be > 0 m");
  const double fy = g.fy > 0 ? g.fy : g.fx;
  BandSegment s;
  s.x_left = g.fx * band.left_m / depth_m + g.cx[LEFT];
  s.x_right = g.fx * band.right_m / depth_m + g.cx[LEFT];
  s.y_top = fy * band.top_m / depth_m + g.cy;
  s.y_bottom = fy * band.bottom_m / depth_m + g.cy;
  return s;
}

cv::Mat rejected_vegetation(const cv::Mat &vegetation, const cv::Mat &canopy)
{
  CV_Assert(vegetation.type() == CV_8UC1);
  cv::Mat out = vegetation > 0;
  if (canopy.empty())
    return out;
  CV_Assert(canopy.type() == CV_8UC1 && canopy.size() == vegetation.size());
  out.setTo(0, canopy);
  return out;
}

std::vector<std::string> metrics_text(const TreeMetrics &m, const TreeMetrics *smoothed,
                                      bool confidence)
{
  if (!m.tree_present)
    return {"no tree"};
  const TreeMetrics *sm = smoothed && smoothed->tree_present ? smoothed : nullptr;
  std::vector<std::string> lines;
  lines.push_back(figure_line("distance", m.distance_m, sm ? &sm->distance_m : nullptr, false));
  lines.push_back(figure_line("height", m.height_m, sm ? &sm->height_m : nullptr,
                              m.clipped.top || m.clipped.bottom));
  lines.push_back(figure_line("width", m.width_m, sm ? &sm->width_m : nullptr,
                              m.clipped.left || m.clipped.right));
  lines.push_back(figure_line("thickness", m.thickness_m, sm ? &sm->thickness_m : nullptr, false));
  lines.push_back("points " + std::to_string(m.points) + ", matches " + std::to_string(m.matches));
  if (confidence) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "conf %.2f", m.confidence);
    lines.push_back(buf);
  }
  return lines;
}

void draw_overlay(cv::Mat &image, const ChannelOrder &order, const OverlayScene &scene,
                  const OverlayStyle &style)
{
  if (order.channels != 3 && order.channels != 4)
    throw BadInput("overlay: only packed 3- or 4-channel colour images can be drawn on");
  if (image.type() != CV_8UC(order.channels))
    throw BadInput("overlay: the image is not 8-bit with " +
                             std::to_string(order.channels) + " channels as its format says");
  for (int c : {order.r, order.g, order.b})
    if (c < 0 || c >= order.channels)
      throw BadInput("overlay: channel order out of range");
  if (scene.n_views != 1 && scene.n_views != 2)
    throw BadInput("overlay: a frame holds 1 or 2 views");
  if (scene.n_views == 2 && image.cols % 2 != 0)
    throw BadInput("overlay: a side-by-side frame must have an even width, got " +
                             std::to_string(image.cols));
  if (image.empty())
    return;
  const int view_width = image.cols / scene.n_views;
  const Painter p{image, order, overlay_scale({view_width, image.rows}), view_width,
                  depth_range(scene, style)};
  if (style.rejected && !scene.rejected.empty())
    draw_rejected(p, scene.rejected);
  if (style.bands)
    draw_bands(p, scene);
  if (style.box || style.contour)
    draw_silhouettes(p, scene, style);
  bool colored = false;
  if (style.matches && !scene.matches.empty()) {
    draw_matches(p, scene, style);
    for (double z : scene.match_depth_m)
      colored = colored || known_depth(z);
  }
  if (style.bands && scene.geometry.valid() && known_depth(scene.band_depth_m))
    for (const Band &b : scene.bands)
      colored = colored || (b.present && known_depth(b.depth_m));
  const bool legend = colored && p.range.second > p.range.first;
  if (style.text && (!scene.text.empty() || legend))
    draw_panel(p, scene, legend);
}

} // namespace treestereo
