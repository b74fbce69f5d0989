// treestereo-synth: renders a sequence of the synthetic orchard as image files, with the rig's
// calibration and the ground truth, as the paper stores its captures (left/right image
// sequences). Used for the committed test fixtures (scripts/make-fixtures.sh) and for trying
// the measuring tool on files. Output is byte-for-byte reproducible for the same options.
// --scene orchard|hedgerow stands the tree in a row (neighbours, a row behind, grass); truth.json
// then also names the scene, the tree in front and the near-row trees in view of each frame.
#include "treestereo/calibration_file.hpp"
#include "treestereo/json.hpp"
#include "treestereo/rectify.hpp"
#include "treestereo/scene.hpp"

#include <glib.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

using namespace treestereo;

namespace {

void write_truth(JsonWriter &w, const GroundTruth &t)
{
  w.begin_object()
      .field("distance_m", t.distance_m)
      .field("depth_p05_m", t.depth_p05_m)
      .field("depth_p95_m", t.depth_p95_m)
      .field("thickness_m", t.thickness_m)
      .key("centroid_m")
      .array({t.centroid_m[0], t.centroid_m[1], t.centroid_m[2]})
      .field("trunk_distance_m", t.trunk_distance_m)
      .end_object();
}

int run(int argc, char **argv)
{
  gint64 seed = 1;
  gint frames = 8;
  gdouble distance = 2.0, speed = 0.0, light = 1.0, noise = 2.0, fps = 7.0, baseline = 50.0;
  gchar *size = nullptr, *out = nullptr, *ext = nullptr, *scene = nullptr, *row_gap = nullptr;
  gdouble row_spacing = -1.0;
  gint touching_pair = -1;
  gint jpeg_quality = 92;
  GOptionEntry entries[] = {
      {"seed", 0, 0, G_OPTION_ARG_INT64, &seed, "Scene seed (default 1)", "N"},
      {"frames", 'n', 0, G_OPTION_ARG_INT, &frames, "Number of frames (default 8)", "N"},
      {"size", 0, 0, G_OPTION_ARG_STRING, &size, "Image size WxH (default 1296x972)", "WxH"},
      {"distance", 0, 0, G_OPTION_ARG_DOUBLE, &distance, "Distance to the trunk, m (2.0)", "M"},
      {"speed", 0, 0, G_OPTION_ARG_DOUBLE, &speed, "Lateral speed, m/s (0)", "M/S"},
      {"fps", 0, 0, G_OPTION_ARG_DOUBLE, &fps, "Frame rate for the speed (7)", "FPS"},
      {"light", 0, 0, G_OPTION_ARG_DOUBLE, &light, "Light level 0.7-1.3 (1.0)", "L"},
      {"noise", 0, 0, G_OPTION_ARG_DOUBLE, &noise, "Sensor noise sigma, 8-bit levels (2)", "S"},
      {"baseline", 0, 0, G_OPTION_ARG_DOUBLE, &baseline, "Baseline, mm (50)", "MM"},
      {"format", 0, 0, G_OPTION_ARG_STRING, &ext, "Image format: png or jpg (png)", "EXT"},
      {"quality", 0, 0, G_OPTION_ARG_INT, &jpeg_quality, "JPEG quality (92)", "Q"},
      {"output", 'o', 0, G_OPTION_ARG_FILENAME, &out, "Output folder (created)", "DIR"},
      {"scene", 0, 0, G_OPTION_ARG_STRING, &scene, "Scene: lab, orchard or hedgerow (lab)", "KIND"},
      {"row-gap", 0, 0, G_OPTION_ARG_STRING, &row_gap,
       "Gap between neighbouring canopies of the row, m (scene's default)", "MIN:MAX"},
      {"row-spacing", 0, 0, G_OPTION_ARG_DOUBLE, &row_spacing,
       "Distance from the row to the next row behind, m (3.5)", "M"},
      {"touching-pair", 0, 0, G_OPTION_ARG_INT, &touching_pair,
       "The canopies of row trees K and K + 1 touch (-1: none)", "K"},
      {nullptr}};
  GOptionContext *ctx = g_option_context_new("- render the synthetic stereo orchard to files");
  g_option_context_set_summary(
      ctx, "Writes DIR/left_%04d.EXT, DIR/right_%04d.EXT, DIR/calibration.yml (the rig's true\n"
           "calibration) and DIR/truth.json (the ground truth of every frame, in the left\n"
           "camera's frame and in the rectified-left frame stereorectify measures in).");
  g_option_context_add_main_entries(ctx, entries, nullptr);
  GError *err = nullptr;
  if (!g_option_context_parse(ctx, &argc, &argv, &err)) {
    std::fprintf(stderr, "treestereo-synth: %s\n", err->message);
    g_error_free(err);
    g_option_context_free(ctx);
    return 2;
  }
  g_option_context_free(ctx);
  if (!out) {
    std::fprintf(stderr, "treestereo-synth: --output DIR is required (see --help)\n");
    return 2;
  }
  const std::string dir = out, fmt = ext ? ext : "png";
  if (fmt != "png" && fmt != "jpg") {
    std::fprintf(stderr, "treestereo-synth: --format must be png or jpg, not '%s'\n", fmt.c_str());
    return 2;
  }
  SceneParams p;
  p.seed = std::uint64_t(seed);
  p.distance_mm = distance * 1000.0;
  p.speed_m_s = speed;
  p.framerate = fps;
  p.light = light;
  p.noise = noise;
  p.baseline_mm = baseline;
  if (scene)
    p.kind = scene_kind_from_name(scene);
  if (row_gap) {
    double lo = 0, hi = 0;
    char end = 0;
    if (std::sscanf(row_gap, "%lf:%lf%c", &lo, &hi, &end) != 2) {
      std::fprintf(stderr, "treestereo-synth: --row-gap expects MIN:MAX in m, got '%s'\n", row_gap);
      return 2;
    }
    p.row_gap_min_mm = lo * 1000.0;
    p.row_gap_max_mm = hi * 1000.0;
  }
  if (row_spacing >= 0)
    p.row_spacing_mm = row_spacing * 1000.0;
  if (touching_pair >= 0)
    p.touching_pair = touching_pair;
  g_free(scene);
  g_free(row_gap);
  if (size) {
    int w = 0, h = 0;
    if (std::sscanf(size, "%dx%d", &w, &h) != 2) {
      std::fprintf(stderr, "treestereo-synth: --size expects WxH, got '%s'\n", size);
      return 2;
    }
    p.image_size = cv::Size(w, h);
  }
  if (frames < 1) {
    std::fprintf(stderr, "treestereo-synth: --frames must be at least 1\n");
    return 2;
  }
  g_free(size);
  g_free(out);
  g_free(ext);

  if (g_mkdir_with_parents(dir.c_str(), 0755) != 0) {
    std::fprintf(stderr, "treestereo-synth: cannot create folder %s\n", dir.c_str());
    return 1;
  }
  SceneRenderer renderer(p); // validates the parameters
  // The left view's x extent per unit depth, for the near-row trees in view.
  double ray_lo = 0, ray_hi = 0;
  {
    std::vector<cv::Mat> xy;
    cv::split(renderer.normalized_rays(0), xy);
    cv::minMaxLoc(xy[0], &ray_lo, &ray_hi);
  }
  save_calibration(renderer.calibration(), dir + "/calibration.yml");
  const StereoRectification rect = compute_rectification(renderer.calibration(), p.image_size);

  std::ofstream truth_file(dir + "/truth.json");
  JsonWriter w(truth_file);
  w.begin_object()
      .field("seed", static_cast<unsigned long long>(p.seed))
      .field("width", p.image_size.width)
      .field("height", p.image_size.height)
      .field("framerate", p.framerate)
      .field("baseline_mm", p.baseline_mm)
      .field("trunk_distance_m", p.distance_mm / 1000.0)
      .field("speed_m_s", p.speed_m_s)
      .field("light", p.light)
      .key("frames")
      .begin_array();
  std::vector<int> params;
  if (fmt == "jpg")
    params = {cv::IMWRITE_JPEG_QUALITY, jpeg_quality};
  else
    params = {cv::IMWRITE_PNG_COMPRESSION, 9};
  for (int f = 0; f < frames; f++) {
    GroundTruth truth[2];
    for (int v = 0; v < 2; v++) {
      cv::Mat rgb, bgr;
      renderer.render(v, std::uint64_t(f), rgb, &truth[v]);
      cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
      char name[64];
      std::snprintf(name, sizeof name, "/%s_%04d.%s", v == 0 ? "left" : "right", f, fmt.c_str());
      if (!cv::imwrite(dir + name, bgr, params))
        throw std::runtime_error("cannot write " + dir + name);
    }
    const GroundTruth &t = truth[0];
    w.begin_object()
        .field("frame", f)
        .field("canopy_height_m", t.canopy_height_m)
        .field("canopy_width_m", t.canopy_width_m)
        .field("canopy_depth_m", t.canopy_depth_m)
        .field("lateral_offset_m", t.lateral_offset_m);
    if (p.kind != SceneKind::Lab) {
      // The near-row trees the left view sees at the trunks' distance.
      const double travel = renderer.travel_mm(std::uint64_t(f));
      w.field("scene", scene_kind_name(p.kind))
          .field("front_tree", t.front_tree)
          .key("row_trees")
          .begin_array();
      for (const RowTree &r :
           renderer.row_trees(travel + ray_lo * p.distance_mm, travel + ray_hi * p.distance_mm))
        w.begin_object()
            .field("index", r.index)
            .field("x_m", r.x_m)
            .field("start_m", r.start_m)
            .field("end_m", r.end_m)
            .field("height_m", r.height_m)
            .field("width_m", r.width_m)
            .field("depth_m", r.depth_m)
            .field("distance_m", r.distance_m)
            .end_object();
      w.end_array();
    }
    w.key("left_camera");
    write_truth(w, t);
    w.key("rectified_left");
    write_truth(w, truth_in_frame(t, rect.geometry.R1));
    w.end_object();
  }
  w.end_array().end_object();
  truth_file << "\n";
  if (!truth_file)
    throw std::runtime_error("cannot write " + dir + "/truth.json");
  std::printf("treestereo-synth: %d frame pairs %dx%d in %s (calibration.yml, truth.json)\n",
              frames, p.image_size.width, p.image_size.height, dir.c_str());
  return 0;
}

} // namespace

int main(int argc, char **argv)
{
  try {
    return run(argc, argv);
  } catch (const std::exception &e) {
    std::fprintf(stderr, "treestereo-synth: %s\n", e.what());
    return 1;
  }
}
