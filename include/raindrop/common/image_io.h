#pragma once
// Reading and writing images: PNG and JPEG through libpng and libjpeg; TIFF, EXR, BMP, WebP and
// the rest through OpenImageIO, in a plugin opened only when such a file is met (OpenImageIO's
// libraries cost 200 ms of start-up; src/common/oiio_codec.h). In: any format either reads;
// out: any format either writes, chosen by the file's extension. Images in memory are cv::Mat
// in RGB(A) order.
//
// Writes are atomic: the image goes to a hidden temporary file in the destination folder
// and is renamed over the final name only when complete, so an interrupted run never leaves
// a half-written image under a final name.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

namespace raindrop {

// The largest image either program reads: 2^26 pixels (67 megapixels, e.g. 8192 x 8192; a
// 50-megapixel camera's 8160 x 6120 fits). Refused from the header, before anything is
// decoded: a PNG of a few hundred KB can declare 16000 x 16000, and rendering that took 3 GB
// (several full-frame copies per worker) and raindrop-remove needs tens of bytes a pixel
// more. At the limit the renderer needs under 1 GB a worker. The same limit in both programs.
inline constexpr std::int64_t kMaxImagePixels = std::int64_t{1} << 26;

struct ImageHeader {
  int width = 0, height = 0, channels = 0;
  int bits = 0;        // bits per channel of the stored data (8, 16, 32, ...)
  bool is_float = false;
  std::string format;  // "png", "jpeg", or OpenImageIO's name for the format
};

// Throws raindrop::Error naming the file for a missing, empty, unreadable or non-image file.
ImageHeader read_header(const std::filesystem::path& path);

// The frame as 8-bit RGB (CV_8UC3). Strict mode accepts only 8-bit, 3-channel images and
// says why otherwise; with `convert`, 16-bit inputs are rounded to 8 bits, float inputs
// (linear light, e.g. EXR) are clamped to [0, 1] and sRGB-encoded, grey is replicated to RGB
// and alpha is dropped (colour kept as stored, not premultiplied).
// Images smaller than `min_size` on a side are refused. Truncated files are errors.
// `stored_png`, if given, receives the file's bytes where they can stand for the returned image
// (a PNG of 8-bit RGB as stored, no palette or transparency, shown as sRGB: an sRGB chunk, or no
// gAMA, cHRM, iCCP or cICP; no chunk that turns or animates it (eXIf, APNG) or is unknown; the
// pixels returned decoded from these very bytes, so not interlaced), so that writing them writes
// that image without encoding it again; else it is cleared.
cv::Mat read_rgb8(const std::filesystem::path& path, bool convert, int min_size = 16,
                  std::string* stored_png = nullptr);

// Throws the Error read_rgb8 would throw for what the file's header shows (missing, empty,
// unreadable or structurally broken, too large or too small, a depth or channel count it
// refuses), without decoding the pixels: cheap enough to check every input of a run before
// its first write. Damage inside the pixel data is found only by read_rgb8.
void check_rgb8_header(const std::filesystem::path& path, bool convert, int min_size = 16);

// The image with its own channels (1-4) and depth: CV_8U or CV_16U (float inputs are refused,
// other integer depths become CV_16U). For raindrop-remove, which keeps size, channels and bit depth.
// With `icc_profile`, also the file's ICC colour profile, for writing it back with the output
// (PNG's iCCP chunk, JPEG's APP2 markers; "" when the file has none, when what it holds is not
// an ICC profile by its header or is over 1 MiB, or for the formats that go through OpenImageIO,
// whose profiles are not carried).
cv::Mat read_image_native(const std::filesystem::path& path, int min_size = 1, std::string* icc_profile = nullptr);

// Throws the Error read_image_native would throw for what the file's header shows, without
// decoding the pixels (as check_rgb8_header does for read_rgb8); returns the image's pixels.
std::int64_t check_native_header(const std::filesystem::path& path, int min_size = 1);

// PNG compression: a zlib level 0-9 with libpng's adaptive row filters; kPngRunLength: zlib's
// run-length strategy over Paeth-filtered rows, both faster and smaller than a zlib level (a
// 2048x1024 street frame: 2.2x faster than level 3 and 12% smaller, smaller even than level 6,
// OpenImageIO's default), because after the Paeth filter a photograph's rows hold few repeated
// strings for LZ77 to find and Huffman coding of the residuals is most of the gain; kPngFast (the
// default): the same Paeth residuals deflated by libdeflate at its fastest level, 2x faster
// again for 13% more bytes than run-length (docs/RESULTS.md section 1).
inline constexpr int kPngRunLength = -1;
inline constexpr int kPngFast = -2;
inline constexpr int kDefaultPngLevel = kPngFast;

// "fast", "rle" or "0".."9" as a png level; throws raindrop::Error otherwise.
int parse_png_level(const std::string& text);
std::string png_level_name(int png_level);

// Writes CV_8U/CV_16U images with 1-4 channels (RGB(A) order) atomically; the format comes
// from the extension (`png_level` applies to PNG). Throws raindrop::Error on failure, leaving no file behind.
// Returns what the format could not hold, in a few words (e.g. "jpeg cannot hold this 16-bit
// RGBA image: rounded to 8 bits, alpha dropped"), or "" when the file keeps the image whole.
// A non-empty `icc_profile` is embedded in a PNG or JPEG (the formats read_image_native reads
// one from), so that a photograph in another colour space than sRGB keeps its colours.
std::string write_image_atomic(const cv::Mat& image, const std::filesystem::path& path, int png_level = kDefaultPngLevel,
                               const std::string& icc_profile = {});

// Images that appear together or not at all (a program's output, mask and contact sheet): each
// is written to a hidden temporary beside its name (stage, which returns what
// write_image_atomic would), and all are moved into place by commit(). Until then the
// destructor removes them, so a destination that fails to write, whatever the reason (a folder
// that even root cannot write, such as /proc; a full disk), leaves none of the others behind.
// commit() renames the last staged first, so the first staged (the main output) replaces its
// file last; a rename that fails there (rare: the file was written beside it) still leaves
// the ones before it in place.
class StagedImages {
 public:
  StagedImages() = default;
  StagedImages(const StagedImages&) = delete;
  StagedImages& operator=(const StagedImages&) = delete;
  ~StagedImages();
  std::string stage(const cv::Mat& image, const std::filesystem::path& path, int png_level = kDefaultPngLevel,
                    const std::string& icc_profile = {});
  // The bytes of `from`, to appear at `path` as a new file (this process's default mode), where
  // they are a JPEG by their signature and by `path`'s extension, and decode exactly to `pixels`
  // (what the caller read from it: the same file, not one put there since): a lossy image left
  // as it was is not encoded again. Its EXIF (orientation included) comes with it. False, and
  // nothing staged, otherwise: the caller writes the pixels.
  bool stage_jpeg_as_it_was(const std::filesystem::path& from, const cv::Mat& pixels, const std::filesystem::path& path);
  void commit();

 private:
  std::vector<std::pair<std::filesystem::path, std::filesystem::path>> pending_;  // temporary, final name
};

// `rgb` (CV_8UC3) encoded as a baseline JPEG of `quality` (1-100, libjpeg's scale, 4:2:0
// chroma) and decoded again, in memory: what a camera that saves JPEG makes of it. Throws raindrop::Error if the
// codec fails.
cv::Mat jpeg_round_trip(const cv::Mat& rgb, int quality);

// Throws a one-line Error naming `path` if write_image_atomic could not write it: no
// writer for its extension, a folder by that name, a parent that is missing (unless
// `folder_may_be_created`), not a folder or not writable, or an existing read-only file. For
// checking every destination of a run before its first write.
void check_image_destination(const std::filesystem::path& path, bool folder_may_be_created = false);

// Throws the one-line Error check_image_destination throws for an existing file at `path` that
// is read-only: the file is written beside its name and renamed over it, which would replace
// it behind its owner's back. (The cheap part of that check, for a run's many destinations.)
// Read-only means: its mode grants nobody write permission (for root too, whom access() lets
// write anything: chmod a-w is how people protect a file, and root replacing it would lose it
// as silently), or this user may not write it.
void check_replaceable(const std::filesystem::path& path);

// The longest file name (bytes) that Linux file systems take (NAME_MAX on ext4, XFS, Btrfs).
inline constexpr std::size_t kMaxFileNameBytes = 255;

// Throws a one-line Error naming `path` if its file name is longer than kMaxFileNameBytes:
// for checking a run's destinations before its work, not after (check_image_destination
// does it too).
void check_file_name_length(const std::filesystem::path& path);

// The part of a file name that its hidden temporary (".<stem>.tmp-<pid>-<n>", beside it in
// its folder) carries: the name itself, cut where the temporary would pass kMaxFileNameBytes.
std::string temporary_stem(const std::string& file_name);

// A hidden temporary's name taken apart: ".<stem>.tmp-<pid>-<n>" gives its stem and the id of
// the process that wrote it; any other name (a user's ".notes.tmp-keep", say) gives nothing.
struct TemporaryName {
  std::string stem;
  long pid = 0;
};
std::optional<TemporaryName> parse_temporary_name(const std::string& file_name);

// Creates the folder if needed and proves it is writable; throws a one-line Error if not.
void ensure_writable_dir(const std::filesystem::path& dir);

// Writes text atomically (temporary file + rename).
void write_text_atomic(const std::string& text, const std::filesystem::path& path);

// A copy of file `from` at `to`, written as write_text_atomic writes (a temporary, then a
// rename): `to` is either the old file or the whole copy.
void copy_file_atomic(const std::filesystem::path& from, const std::filesystem::path& to);

}  // namespace raindrop
