#include "raindrop/render/render_job.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <mutex>
#include <optional>
#include <set>

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <nlohmann/json.hpp>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "raindrop/common/error.h"
#include "raindrop/common/image_files.h"
#include "raindrop/common/image_io.h"
#include "raindrop/common/progress.h"
#include "raindrop/common/rng.h"
#include "raindrop/common/version.h"
#include "raindrop/render/defocus.h"
#include "raindrop/render/effect_policy.h"
#include "raindrop/render/framing.h"
#include "raindrop/render/manifest.h"
#include "raindrop/render/sensor.h"
#include "raindrop/render/veil.h"
#include "raindrop/render/scene.h"

namespace raindrop {
namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

constexpr double kDeg = 180.0 / M_PI;

std::string hex64(std::uint64_t v) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(v));
  return buf;
}

// Everything that changes the bytes of a sample.
std::string job_fingerprint(const RenderOptions& o) {
  std::string key = renderer_version() + "\n" + scene_to_json(o.scene) + "\n" + std::to_string(o.seed) + "\n" +
                    (o.size ? std::to_string(o.size->width) + "x" + std::to_string(o.size->height) : "native") +
                    "\n" + (o.convert ? "convert" : "strict");
  return hex64(hash_string(key));
}

// The output folder's lock, held for a run: a second run into the same folder would delete
// the first's temporaries (remove_stale_temporaries) and interleave their manifests. The
// kernel's flock() on <out>/.raindrop-render.lock is the lock, so a killed run's lock is
// released with it (a file left behind is stale and simply taken over); the file holds the
// owner's pid for the message a second run prints.
//
// Shards (--shard K/N) hold the folder's lock shared, so that they run side by side, and
// each the exclusive lock of its own shard, <out>/.raindrop-render.shard-K-of-N.lock; a whole
// run and --merge-shards hold the folder's lock exclusively.
class OutputLock {
 public:
  // `what` names the locked thing in the message ("output folder 'out'").
  OutputLock(fs::path path, bool shared, const std::string& what) : path_(std::move(path)), shared_(shared) {
    // A shard can find the file held exclusively for a moment by another shard that is
    // finishing (release below): it tries again for about a second.
    for (int attempt = 0;; ++attempt) {
      fd_ = ::open(path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
      if (fd_ < 0) throw Error("cannot create the lock file '" + path_.string() + "' (" + std::strerror(errno) + ")");
      if (::flock(fd_, (shared ? LOCK_SH : LOCK_EX) | LOCK_NB) != 0) {
        const int err = errno;
        char pid[32] = {0};
        const ssize_t n = ::pread(fd_, pid, sizeof pid - 1, 0);
        ::close(fd_);
        fd_ = -1;
        if (err == EWOULDBLOCK && shared && attempt < 50) {
          ::usleep(20000);
          continue;
        }
        std::string owner(pid, n > 0 ? static_cast<size_t>(n) : 0);
        while (!owner.empty() && std::isspace(static_cast<unsigned char>(owner.back()))) owner.pop_back();
        if (err == EWOULDBLOCK)
          throw Error(what + " is in use by another raindrop-render" +
                      (owner.empty() ? std::string() : " (pid " + owner + ")") +
                      "; wait for it to finish or choose another folder");
        throw Error("cannot lock '" + path_.string() + "' (" + std::strerror(err) + ")");
      }
      // The previous owner unlinks the file when it finishes: if that happened between our
      // open and flock, we hold a lock on a file no one else will see; start again.
      struct stat held {}, named {};
      if (::fstat(fd_, &held) == 0 && ::stat(path_.c_str(), &named) == 0 && held.st_dev == named.st_dev &&
          held.st_ino == named.st_ino)
        break;
      ::close(fd_);
    }
    const std::string pid = std::to_string(::getpid()) + "\n";
    if (::ftruncate(fd_, 0) != 0 || ::pwrite(fd_, pid.data(), pid.size(), 0) != static_cast<ssize_t>(pid.size())) {
      const int err = errno;
      release();
      throw Error("cannot write the lock file '" + path_.string() + "' (" + std::strerror(err) + ")");
    }
  }
  ~OutputLock() { release(); }
  OutputLock(const OutputLock&) = delete;
  OutputLock& operator=(const OutputLock&) = delete;

 private:
  void release() {
    if (fd_ < 0) return;
    // A shared holder removes the file only when it is the last: when it can take the lock
    // exclusively.
    if (!shared_ || ::flock(fd_, LOCK_EX | LOCK_NB) == 0)
      ::unlink(path_.c_str());  // while still locked: see the inode check above
    ::close(fd_);
    fd_ = -1;
  }
  fs::path path_;
  bool shared_ = false;
  int fd_ = -1;
};

fs::path folder_lock_path(const fs::path& dir) { return dir / ".raindrop-render.lock"; }
std::string folder_description(const fs::path& dir) { return "output folder '" + dir.string() + "'"; }

// `only`: remove just the temporaries of these files (a shard's own: the other shards may be
// writing theirs right now), given as their temporary_stem (image_io.h); nullptr: all.
void remove_stale_temporaries(const fs::path& dir, const std::set<std::string>* only = nullptr) {
  std::error_code ec;
  for (auto it = fs::directory_iterator(dir, ec); !ec && it != fs::directory_iterator(); it.increment(ec)) {
    const std::string name = it->path().filename().string();
    // Only names this program gives its temporaries, the stem a PNG or a manifest: a user's
    // own hidden ".notes.tmp-keep" is left alone.
    const auto temporary = parse_temporary_name(name);
    if (!temporary) continue;
    const std::string& stem = temporary->stem;
    const std::string ext = lowercase_extension(fs::path(stem));
    if (ext != ".png" && ext != ".jsonl") continue;
    if (!only || only->count(stem)) fs::remove(it->path(), ec);
  }
}

json drop_record(const DropShape& d, bool gravity, double coc_px, bool lens) {
  json j = {{"center_cm", {d.center.x, d.center.y}},
            {"footprint_radius_cm", d.footprint_radius},
            {"sphere_radius_cm", d.sphere_radius()},
            {"contact_angle_deg", d.contact_angle * kDeg},
            {"height_cm", d.height()}};
  if (lens) j["coc_px"] = coc_px;
  if (gravity) {
    j["elongation"] = d.elongation;
    j["flattening"] = d.flattening;
  }
  // An irregular contact line: footprint_radius_cm is then the circle it stretches (outline.h).
  if (!d.outline.circular()) {
    j["outline"] = {{"peak_deviation", d.outline.peak_deviation()},
                    {"cos", d.outline.cos_terms()},
                    {"sin", d.outline.sin_terms()}};
  }
  // A cap of a trail (trails.h): the index of the drop that left it, in this list.
  if (d.trail_of >= 0) j["trail_of"] = d.trail_of;
  return j;
}

// What the scene's "auto" effects decided for a frame, and why (effect_policy.h).
json effects_auto_record(const SceneConfig& config, const RenderedFrame& rendered) {
  const EffectPlan& plan = rendered.effects;
  json out = json::object();
  auto per_drop = [&](bool DropEffects::*on, const std::string& why) {
    int count = 0;
    for (const DropEffects& d : plan.drops) count += d.*on;
    return json{{"on", count > 0},
                {"drops_on", count},
                {"drops_off", static_cast<int>(plan.drops.size()) - count},
                {"why", why}};
  };
  if (plan.dispersion_auto) out["dispersion"] = per_drop(&DropEffects::dispersion, dispersion_why(plan));
  if (plan.gravity_auto) out["gravity"] = per_drop(&DropEffects::gravity, gravity_why(plan));
  if (plan.supersample_auto) {
    const TraceStats& s = rendered.stats;
    out["supersample"] = {{"on", s.supersampled_pixels > 0},
                          {"pixels", s.supersampled_pixels},
                          {"inside_aliasing", s.aliasing_pixels},
                          {"inside_one_sample", s.smooth_pixels},
                          {"why", supersample_why(s.aliasing_pixels, s.smooth_pixels, config.samples_per_pixel)}};
  }
  return out;
}

// Whether the lens spread some drop (else only the street: the aperture reference, focus off it).
bool some_drop_spread(const RenderedFrame& rendered) {
  return std::any_of(rendered.coc_px.begin(), rendered.coc_px.end(), [](double c) { return c >= kMinVisibleCocPx; });
}

// The highlights' lift the frame's light went through, which the veil then scatters (veil.h):
// the sample's, where it ran on this frame; none otherwise.
HighlightLift lift_that_ran(const RenderedFrame& rendered, const SceneSample& scene) {
  return rendered.highlights_lifted ? scene.highlights : HighlightLift{};
}

json sample_record(const std::string& id, const InputImage& input, int variant, std::uint64_t seed,
                   const Frame& frame, const SceneConfig& config, const SceneSample& scene,
                   const RenderedFrame& rendered, const VeilSample& veil, const SensorSample& sensor,
                   const std::string& job) {
  json drops = json::array();
  // The drops as rendered (gravity undone where auto skipped it).
  const std::vector<DropShape> shapes = rendered_shapes(scene, rendered.effects);
  for (size_t i = 0; i < shapes.size(); ++i) {
    drops.push_back(drop_record(shapes[i], config.gravity.enabled,
                                i < rendered.coc_px.size() ? rendered.coc_px[i] : 0.0, config.lens.enabled));
    const EffectPlan& plan = rendered.effects;
    if (plan.dispersion_auto)
      drops.back()["dispersion"] = {{"on", plan.drops[i].dispersion}, {"spread_px", plan.drops[i].spread_px},
                                    {"levels", plan.drops[i].dispersion_levels}};
    if (plan.gravity_auto)
      drops.back()["gravity"] = {{"on", plan.drops[i].gravity}, {"shift_px", plan.drops[i].gravity_px},
                                 {"levels", plan.drops[i].gravity_levels}};
  }
  const double px = static_cast<double>(rendered.stats.drop_pixels);
  json record{{"id", id},
              {"rainy", "rainy/" + id + ".png"},
              {"clean", "clean/" + id + ".png"},
              {"mask", "mask/" + id + ".png"},
              {"width", frame.clean.cols},
              {"height", frame.clean.rows},
              {"source", input.path.string()},
              {"split", input.split},
              {"variant", variant},
              {"seed", seed},
              {"camera", {{"fx", frame.camera.fx}, {"fy", frame.camera.fy}, {"cx", frame.camera.cx},
                          {"cy", frame.camera.cy}, {"origin", frame.camera_origin}}},
              {"scene", {{"preset", config.name},
                         {"glass_distance_cm", scene.glass.distance},
                         {"background_distance_cm", scene.background_distance_cm},
                         {"tilt_deg", scene.glass.tilt * kDeg},
                         {"blur_diameter_px", scene.blur_diameter_px},
                         {"refractive_index", config.refractive_index},
                         {"drops_requested", scene.drops_requested},
                         {"geometry", config.geometry.describe()},
                         {"samples_per_pixel", config.samples_per_pixel},
                         {"border", to_string(config.border)}}},
              {"effects", config.effect_names()},
              {"drops", drops},
              {"coverage", rendered.coverage()},
              {"dark_band_fraction", px > 0 ? rendered.stats.dark_band_pixels / px : 0.0},
              {"off_frame_fraction", px > 0 ? rendered.stats.off_frame_pixels / px : 0.0},
              {"renderer", "raindrop-render " + renderer_version()},
              {"job", job}};
  if (rendered.effects.any_auto()) record["effects_auto"] = effects_auto_record(config, rendered);
  if (config.lens.enabled) {
    const std::string budget = std::to_string(static_cast<int>(kAutoBudgetLevels)) + " levels";
    record["alpha"] = "alpha/" + id + ".png";
    record["lens"] = {{"f_number", scene.f_number},
                      {"focal_length_mm", scene.focal_length_mm},
                      {"aperture_cm", scene.aperture_cm()},
                      {"focus_distance_cm", scene.focus_cm()},
                      {"background_coc_px", scene.background_coc_px(frame.camera.fx)},
                      {"background_defocused", !rendered.clean.empty()},
                      {"defocus", rendered.defocused ? to_string(config.lens.method) : "skipped"},
                      {"why", !rendered.defocused
                                  ? (config.lens.trace_in_focus || config.lens.method == DefocusMethod::Aperture
                                         ? "every drop's circle of confusion is under 0.5 px, and no drop's spread "
                                           "through the aperture moves a pixel by " + budget + " or more"
                                         : "every drop's circle of confusion is under 0.5 px (drops in focus through "
                                           "the lens' centre: drops_in_focus)")
                              : some_drop_spread(rendered) ? "some drop's circle of confusion is at least 0.5 px"
                              : rendered.lens_sampled ? "some drop's spread through the aperture (circle and parallax) "
                                                        "moves a pixel by " + budget + " or more: traced through it"
                                                      : "the street's circle of confusion is at least 0.5 px "
                                                        "(the aperture reference traces it)"},
                      {"drops_traced_through_aperture", rendered.lens_sampled_drops},
                      {"mask_threshold", config.lens.mask_threshold}};
  }
  if (config.highlights.enabled)
    record["highlights"] = {{"gain", scene.highlights.gain},
                            {"threshold", config.highlights.threshold},
                            {"on", rendered.highlights_lifted},
                            {"why", rendered.highlights_lifted    ? "some pixel is at or above the threshold"
                                    : !scene.highlights.active() ? "the gain is 1 (nothing to lift)"
                                    : rendered.defocused || !rendered.clean.empty() ? "no pixel reaches the threshold"
                                                                 : "the lens was skipped (nothing is spread)"}};
  if (config.veil.enabled) {
    const HighlightLift lift = lift_that_ran(rendered, scene);
    record["veil"] = {{"optical_depth", veil.optical_depth},
                      {"scattered_fraction", veil.scattered()},
                      {"spread_deg", veil.spread_deg},
                      {"sigma_px", veil.sigma_px},
                      {"on", veil.visible(lift)},
                      {"why", veil.visible(lift) ? "the scattered light can move a pixel by half a level or more"
                                             : "the scattered light cannot move any pixel by half a level"},
                      {"applies_to", "rainy"}};
  }
  if (config.sensor.enabled)
    record["sensor"] = {{"noise_sigma", sensor.noise_sigma}, {"jpeg_quality", sensor.jpeg_quality},
                        {"applies_to", "rainy"}};
  return record;
}

std::string variant_id(const std::string& input_id, int variant) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "_v%02d", variant);
  return input_id + buf;
}

// The input id of a sample id: variant_id appends "_v<digits>" to it.
std::string input_of(const std::string& sample_id) {
  const auto v = sample_id.rfind("_v");
  return v == std::string::npos ? sample_id : sample_id.substr(0, v);
}

}  // namespace

cv::Mat alpha16(const RenderedFrame& f) {
  cv::Mat out;
  if (f.alpha.empty()) {
    f.mask.convertTo(out, CV_16U, 65535.0 / 255.0);
  } else {
    f.alpha.convertTo(out, CV_16U, 65535.0);
  }
  return out;
}

bool frame_is_stored_input(const cv::Mat& rgb, const Frame& frame, const std::string& stored_png) {
  return !stored_png.empty() && frame.clean.data == rgb.data && frame.clean.size() == rgb.size();
}

std::string renderer_version() { return kVersion; }

std::uint64_t sample_seed(std::uint64_t run_seed, const std::string& input_id, int variant) {
  return mix64(mix64(run_seed) ^ hash_string(input_id) ^ mix64(0x5eed0000ULL + static_cast<std::uint64_t>(variant)));
}

RenderSummary render_dataset(const std::vector<InputImage>& inputs, const RenderOptions& o) {
  const auto start = std::chrono::steady_clock::now();
  if (o.variants < 1) throw Error("--variants must be at least 1");
  check_unique_ids(inputs);
  const bool sharded = o.shard.sharded();
  // A refused run writes nothing. A folder that exists is locked before its manifests are read
  // (the lock files go when the run ends); a new folder is made, and locked, only once every
  // input's header has passed (below). Shards share the folder, each holding its own part.
  std::error_code ec;
  const bool existed = fs::exists(o.out_dir, ec);
  std::optional<OutputLock> folder_lock, shard_lock;
  const auto lock_folder = [&] {
    ensure_writable_dir(o.out_dir);
    folder_lock.emplace(folder_lock_path(o.out_dir), sharded, folder_description(o.out_dir));
    if (sharded)
      shard_lock.emplace(o.out_dir / (".raindrop-render.shard-" + std::to_string(o.shard.index) + "-of-" +
                                      std::to_string(o.shard.count) + ".lock"),
                         false, "shard " + o.shard.text() + " of " + folder_description(o.out_dir));
  };
  if (existed) lock_folder();
  // The samples this run renders. A shard's: every variant of the inputs whose id hashes to
  // it (shard.h), so that no two shards decode one image.
  struct Task {
    const InputImage* input;
    std::vector<int> variants;
  };
  std::vector<Task> tasks;
  for (const auto& in : inputs) {
    if (!o.shard.owns(in.id)) continue;
    Task t{&in, {}};
    for (int v = 0; v < o.variants; ++v) t.variants.push_back(v);
    tasks.push_back(std::move(t));
  }
  const std::string manifest_file = manifest_name(o.shard);
  std::set<std::string> own_files{manifest_file};
  for (const auto& t : tasks) {
    for (int v : t.variants) {
      const std::string name = variant_id(t.input->id, v) + ".png";
      check_file_name_length(o.out_dir / "rainy" / name);  // before any work, not after the render
      own_files.insert(temporary_stem(name));
    }
  }
  const fs::path manifest_path = o.out_dir / manifest_file;
  const std::string job = job_fingerprint(o);
  // A shard resumes from its part and from its samples in a merged manifest.jsonl; a whole
  // run from manifest.jsonl and every shard's part, which it merges into manifest.jsonl.
  auto existing = read_manifest(manifest_path);
  std::vector<std::pair<fs::path, Shard>> parts;
  std::vector<fs::path> also;
  if (sharded) {
    also.push_back(o.out_dir / manifest_name(Shard{}));
    // The merge refuses parts of runs split different ways: say so before this shard renders
    // its share, not after every shard has.
    for (const auto& [file, shard] : find_manifest_parts(o.out_dir)) {
      if (shard.count != o.shard.count)
        throw Error("'" + o.out_dir.string() + "' holds " + file.filename().string() + ", a part of a run split " +
                    std::to_string(shard.count) + " ways, and --shard " + o.shard.text() + " splits it " +
                    std::to_string(o.shard.count) + " ways; use --shard K/" + std::to_string(shard.count) +
                    ", or first finish that run (a run without --shard renders what its shards left and merges them)");
    }
  } else {
    parts = find_manifest_parts(o.out_dir);
    for (const auto& part : parts) also.push_back(part.first);
  }
  for (const auto& file : also) {
    for (auto& [id, entry] : read_manifest(file)) {
      if (o.shard.owns(input_of(id))) existing.emplace(id, std::move(entry));
    }
  }
  // A sample is this run's only if it came from this run's input of that name: resuming from
  // a sample of another image that had the same name (rA/x.png, then rB/x.png) would keep it
  // as done, under a manifest that names the other image. The recorded name is as that run gave
  // it (perhaps relative to another working folder), so only a recorded image that is here and
  // is another file than this run's counts.
  std::map<std::string, fs::path> source_of;
  for (const auto& t : tasks) source_of[t.input->id] = t.input->path;
  std::map<std::string, ManifestEntry> kept;
  for (const auto& [id, entry] : existing) {
    if (entry.job != job)
      throw Error("'" + o.out_dir.string() + "' holds samples rendered with other settings (scene, seed, size, "
                  "--convert or renderer version); render into a new folder or delete that one");
    const auto input = source_of.find(input_of(id));
    std::error_code differs;
    if (input != source_of.end() && !entry.source.empty() && fs::is_regular_file(entry.source, ec) &&
        fs::exists(input->second, ec) && !fs::equivalent(entry.source, input->second, differs) && !differs)
      throw Error("'" + o.out_dir.string() + "' holds sample " + id + " rendered from '" + entry.source +
                  "', but this run's input of that name is '" + input->second.string() +
                  "'; render into a new folder, or delete that one");
    bool complete = true;
    for (const auto& f : entry.files) complete = complete && fs::exists(o.out_dir / f);
    if (complete) kept[id] = entry;
  }

  RenderSummary summary;
  std::vector<std::string> resumed;  // this run's samples an earlier run rendered
  for (auto& t : tasks) {
    const auto done = std::remove_if(t.variants.begin(), t.variants.end(), [&](int v) {
      const std::string id = variant_id(t.input->id, v);
      if (kept.count(id) == 0) return false;
      resumed.push_back(id);
      return true;
    });
    summary.skipped += static_cast<std::int64_t>(t.variants.end() - done);
    t.variants.erase(done, t.variants.end());
  }
  // The contact sheet shows this run's first samples by id, whichever run rendered them: those
  // already done are read back (a resumed run wrote a sheet of only what it rendered, or none).
  if (o.contact_sheet_rows > 0) {
    std::sort(resumed.begin(), resumed.end());
    if (static_cast<int>(resumed.size()) > o.contact_sheet_rows) resumed.resize(o.contact_sheet_rows);
    for (const std::string& id : resumed) {
      const ManifestEntry& e = kept.at(id);
      try {
        summary.samples.push_back({id, read_image_native(o.out_dir / e.files[1]),
                                   read_image_native(o.out_dir / e.files[0]), read_image_native(o.out_dir / e.files[2])});
      } catch (const Error&) {
        // A done sample damaged since is left off the sheet: the render does not read it.
      }
    }
  }
  tasks.erase(std::remove_if(tasks.begin(), tasks.end(), [](const Task& t) { return t.variants.empty(); }),
              tasks.end());

  const int threads = o.threads > 0 ? o.threads : static_cast<int>(std::thread::hardware_concurrency());
  // Embree and TBB size their pools from this; the arena bounds our own parallelism.
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<size_t>(threads));
  tbb::task_arena arena(threads);

  // Check every input's header (readable, size, depth, channels: all that read_rgb8 refuses
  // without decoding) before writing anything, so that a refused file in a large run is
  // reported at once rather than hours in, and leaves no folder, manifest or sample behind.
  if (!o.keep_going) {
    std::vector<std::string> header_errors(tasks.size());
    arena.execute([&] {
      tbb::parallel_for(size_t{0}, tasks.size(), [&](size_t i) {
        try {
          check_rgb8_header(tasks[i].input->path, o.convert);
        } catch (const Error& e) {
          header_errors[i] = e.what();
        }
      });
    });
    for (const auto& e : header_errors) {
      if (!e.empty()) throw Error(e);
    }
  }
  // The folders a sample's images go to (alpha/: the aperture's coverage, with a lens only).
  std::vector<std::string> image_dirs{"rainy", "clean", "mask"};
  if (o.scene.lens.enabled) image_dirs.push_back("alpha");
  // The files a resumed run writes over (an incomplete sample's images, the manifest it
  // rewrites): one made read-only is kept, and the run stops here, before any write (image_io.h).
  if (existed) {
    if (fs::exists(manifest_path, ec)) check_replaceable(manifest_path);
    for (const auto& t : tasks) {
      for (int v : t.variants) {
        for (const auto& dir : image_dirs) check_replaceable(o.out_dir / dir / (variant_id(t.input->id, v) + ".png"));
      }
    }
  }
  if (!existed) {
    lock_folder();
    // Another run may have made and filled the folder meanwhile: its manifests were not read.
    if (fs::exists(manifest_path, ec) || fs::exists(o.out_dir / manifest_name(Shard{}), ec) ||
        (!sharded && !find_manifest_parts(o.out_dir).empty()))
      throw Error("output folder '" + o.out_dir.string() + "' was created by another run while this one started; run again");
  }
  std::vector<std::string> subs{""};
  subs.insert(subs.end(), image_dirs.begin(), image_dirs.end());
  for (const auto& sub : subs) {
    ensure_writable_dir(o.out_dir / sub);
    remove_stale_temporaries(o.out_dir / sub, sharded ? &own_files : nullptr);
  }

  std::int64_t todo = 0;
  for (const auto& t : tasks) todo += static_cast<std::int64_t>(t.variants.size());
  Progress progress(todo, "render", o.progress);
  // Start from the complete records only: an interrupted append leaves a partial last line,
  // which must not be glued to the next record.
  if (fs::exists(manifest_path)) {
    std::string text;
    for (const auto& [id, entry] : kept) text += entry.line + "\n";
    write_text_atomic(text, manifest_path);
  }
  ManifestWriter manifest(manifest_path);
  std::atomic<bool> stop{false};
  std::mutex summary_mutex;

  arena.execute([&] {
    tbb::parallel_for(
        tbb::blocked_range<size_t>(0, tasks.size(), 1),
        [&](const tbb::blocked_range<size_t>& range) {
          for (size_t i = range.begin(); i < range.end(); ++i) {
            const Task& task = tasks[i];
            if (stop) return;
            size_t finished = 0;
            try {
              std::string input_png;
              const cv::Mat rgb = read_rgb8(task.input->path, o.convert, 16, &input_png);
              const Frame frame = make_frame(rgb, task.input->calibration, o.size);
              // The clean image as the input file's bytes where they stand for it: one of a
              // frame's three encodes saved, about a third of its time at 2048x1024.
              const bool clean_is_input = frame_is_stored_input(rgb, frame, input_png);
              // Every variant of an input focused on its background has the same clean image:
              // encoded once, then copied (encoding is most of a frame's time; a copy of the
              // bytes is a fraction of it). A defocused street is each variant's own.
              std::optional<fs::path> clean_written;
              for (int v : task.variants) {
                if (stop) return;
                const std::string id = variant_id(task.input->id, v);
                const std::uint64_t seed = sample_seed(o.seed, task.input->id, v);
                Rng rng(seed);
                const SceneSample scene = sample_scene(o.scene, frame.camera, rng);
                const RenderedFrame rendered = render_frame(frame.clean, frame.camera, o.scene, scene);
                // The wet glass' veil (veil.h), then the camera's noise and compression
                // (sensor.h): on the rainy image only.
                const VeilSample veil = sample_veil(o.scene, frame.camera.fx, seed);
                const HighlightLift veil_lift = lift_that_ran(rendered, scene);
                const SensorSample sensor = sample_sensor(o.scene, seed);
                cv::Mat rainy = rendered.rainy;
                if (veil.visible(veil_lift) || sensor.any()) rainy = rendered.rainy.clone();
                if (veil.visible(veil_lift)) apply_veil(rainy, veil, veil_lift);
                if (sensor.any()) apply_sensor(rainy, sensor, seed);
                // alpha first: a sample whose three main images exist (what resume checks)
                // then has its alpha too.
                if (o.scene.lens.enabled)
                  write_image_atomic(alpha16(rendered), o.out_dir / "alpha" / (id + ".png"), o.png_level);
                write_image_atomic(rainy, o.out_dir / "rainy" / (id + ".png"), o.png_level);
                const fs::path clean_path = o.out_dir / "clean" / (id + ".png");
                if (clean_written && rendered.clean.empty()) {
                  copy_file_atomic(*clean_written, clean_path);
                } else if (clean_is_input && rendered.clean.empty()) {
                  write_text_atomic(input_png, clean_path);  // the bytes as they are
                } else {
                  write_image_atomic(rendered.clean_or(frame.clean), clean_path, o.png_level);
                }
                if (rendered.clean.empty()) clean_written = clean_path;
                write_image_atomic(rendered.mask, o.out_dir / "mask" / (id + ".png"), o.png_level);
                // A source path that is not UTF-8 (file names are bytes) cannot be JSON: such
                // bytes are written as U+FFFD instead of stopping the run after the images.
                manifest.append(id, sample_record(id, *task.input, v, seed, frame, o.scene, scene, rendered, veil, sensor, job)
                                        .dump(-1, ' ', false, json::error_handler_t::replace));
                ++finished;
                {
                  std::lock_guard<std::mutex> lock(summary_mutex);
                  ++summary.rendered;
                  summary.coverage_sum += rendered.coverage();
                  // Drops, not the caps of their trails.
                  summary.drops_sum += std::count_if(scene.drops.begin(), scene.drops.end(),
                                                     [](const DropShape& d) { return d.trail_of < 0; });
                  if (o.contact_sheet_rows > 0) {
                    summary.samples.push_back({id, rendered.clean_or(frame.clean), rainy, rendered.mask});
                    std::sort(summary.samples.begin(), summary.samples.end(),
                              [](const SampleView& a, const SampleView& b) { return a.id < b.id; });
                    if (static_cast<int>(summary.samples.size()) > o.contact_sheet_rows) summary.samples.pop_back();
                  }
                }
                progress.advance();
              }
            } catch (const std::exception& e) {
              std::lock_guard<std::mutex> lock(summary_mutex);
              summary.failed += static_cast<std::int64_t>(task.variants.size() - finished);
              summary.errors.push_back(e.what());
              if (!o.keep_going) stop = true;
            }
          }
        },
        tbb::simple_partitioner());
  });
  progress.finish();
  manifest.finalize(kept);
  // Their samples are in manifest.jsonl now.
  for (const auto& part : parts) fs::remove(part.first, ec);
  // A run that made the folder and rendered nothing in it (its first input failed to decode)
  // leaves nothing behind, as one refused before any write does: its empty manifest and
  // folders go. Only what is empty is removed; a shard leaves the shared folder to the others.
  if (!existed && !sharded && summary.rendered == 0 && kept.empty() && !summary.errors.empty()) {
    folder_lock.reset();
    shard_lock.reset();
    if (fs::is_regular_file(manifest_path, ec) && fs::file_size(manifest_path, ec) == 0) fs::remove(manifest_path, ec);
    for (const auto& dir : image_dirs) fs::remove(o.out_dir / dir, ec);  // only if empty
    fs::remove(o.out_dir, ec);                                          // only if empty
  }
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

std::int64_t merge_shards(const fs::path& dir) {
  if (!fs::is_directory(dir)) throw Error("'" + dir.string() + "' is not a folder");
  const OutputLock folder_lock(folder_lock_path(dir), false, folder_description(dir));
  const auto parts = find_manifest_parts(dir);
  if (parts.empty()) throw Error("'" + dir.string() + "' holds no manifest parts (manifest.part-K-of-N.jsonl)");
  const int n = parts.front().second.count;
  std::set<int> have;
  for (const auto& [file, shard] : parts) {
    if (shard.count != n)
      throw Error("'" + dir.string() + "' holds the parts of runs split " + std::to_string(n) + " and " +
                  std::to_string(shard.count) + " ways; merge needs the parts of one run");
    have.insert(shard.index);
  }
  // After an earlier merge, only the shards rerun since have parts.
  const bool merged_before = fs::exists(dir / manifest_name(Shard{}));
  for (int k = 0; k < n && !merged_before; ++k) {
    if (!have.count(k))
      throw Error("'" + (dir / manifest_name(Shard{k, n})).string() + "' is missing: shard " + Shard{k, n}.text() +
                  " has not run; run it, then merge");
  }
  std::map<std::string, std::string> lines;
  std::string job;
  std::vector<fs::path> files{dir / manifest_name(Shard{})};
  for (const auto& part : parts) files.push_back(part.first);
  for (const auto& file : files) {
    for (const auto& [id, entry] : read_manifest(file)) {
      if (job.empty()) job = entry.job;
      if (entry.job != job)
        throw Error("'" + file.string() + "' holds samples rendered with other settings than the rest of '" +
                    dir.string() + "'");
      lines[id] = entry.line;
    }
  }
  write_manifest(lines, dir / manifest_name(Shard{}));
  for (const auto& part : parts) {
    std::error_code ec;
    fs::remove(part.first, ec);
  }
  return static_cast<std::int64_t>(lines.size());
}

}  // namespace raindrop
