// raindrop_oiio.so: image formats through OpenImageIO, for raindrop_common's image_io.cpp
// (src/common/oiio_codec.h says why this is a plugin). The front end has already checked that
// the file exists, is not empty and, for a PNG, is structurally sound.
#include <cstddef>
#include <memory>
#include <string>

#include <OpenImageIO/imageio.h>

#include "../common/exif_orientation.h"
#include "../common/format_loss.h"
#include "../common/oiio_codec.h"
#include "raindrop/common/error.h"
#include "raindrop/common/srgb_curve.h"

namespace raindrop::oiio {
namespace fs = std::filesystem;
namespace {

// First line of an OIIO error message (they can be multi-line).
std::string first_line(std::string s) {
  const auto nl = s.find('\n');
  if (nl != std::string::npos) s.resize(nl);
  return s.empty() ? "unknown error" : s;
}

bool is_float(const OIIO::TypeDesc& t) {
  return t.basetype == OIIO::TypeDesc::FLOAT || t.basetype == OIIO::TypeDesc::HALF ||
         t.basetype == OIIO::TypeDesc::DOUBLE;
}

std::unique_ptr<OIIO::ImageInput> open_input(const fs::path& path) {
  // Keep colour values as stored when there is alpha (PNG is unassociated).
  OIIO::ImageSpec config;
  config.attribute("oiio:UnassociatedAlpha", 1);
  auto in = OIIO::ImageInput::open(path.string(), &config);
  if (!in) throw Error(quoted(path) + ": not a readable image (" + first_line(OIIO::geterror()) + ")");
  const OIIO::ImageSpec& spec = in->spec();
  if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0) throw Error(quoted(path) + ": image has no pixels");
  return in;
}

// The file's Orientation (EXIF or TIFF tag, 1-8; exif_orientation.h), 1 when it has none. PNG
// is read as stored, as libpng reads the PNGs that do not come here (an eXIf chunk in a palette
// PNG must not turn it when the same picture in RGB would not be).
int orientation_of(const OIIO::ImageInput& in) {
  if (std::string(in.format_name()) == "png") return 1;
  const int o = in.spec().get_int_attribute("Orientation", 1);
  return o >= 1 && o <= 8 ? o : 1;
}

ImageHeader read_header(const fs::path& path) {
  auto in = open_input(path);
  const OIIO::ImageSpec& spec = in->spec();
  ImageHeader h;
  // As shown, like JPEG files through libjpeg (jpeg_file.h).
  const bool swapped = exif::swaps_sides(orientation_of(*in));
  h.width = swapped ? spec.height : spec.width;
  h.height = swapped ? spec.width : spec.height;
  h.channels = spec.nchannels;
  h.bits = static_cast<int>(spec.format.size() * 8);
  h.is_float = is_float(spec.format);
  h.format = in->format_name();
  in->close();
  return h;
}

cv::Mat decode(const fs::path& path) {
  auto in = open_input(path);
  const OIIO::ImageSpec spec = in->spec();
  const int nc = spec.nchannels;
  if (nc > 4) throw Error(quoted(path) + ": " + std::to_string(nc) + " channels are not supported (grey, grey+alpha, RGB or RGBA)");
  const bool floating = is_float(spec.format);
  const bool eight = spec.format == OIIO::TypeDesc::UINT8 || spec.format == OIIO::TypeDesc::INT8;
  const OIIO::TypeDesc type = floating ? OIIO::TypeDesc::FLOAT : eight ? OIIO::TypeDesc::UINT8 : OIIO::TypeDesc::UINT16;
  cv::Mat image(spec.height, spec.width, floating ? CV_32FC(nc) : eight ? CV_8UC(nc) : CV_16UC(nc));
  // A decoder can report a problem and still return success: libjpeg only warns at a premature
  // end of file and fills the missing rows with grey, which OIIO records as an error on the
  // ImageInput. Any recorded error is a failed decode.
  const bool ok = in->read_image(0, 0, 0, nc, type, image.data);
  if (!ok || in->has_error()) throw Error(quoted(path) + ": cannot decode (" + first_line(in->geterror()) + ")");
  const int orientation = orientation_of(*in);
  in->close();
  exif::make_upright(image, orientation);
  return image;
}

// `data` (8/16-bit, sRGB-encoded colour, linear alpha) as linear-light floats, for a format
// that stores only floats (OpenEXR, Radiance HDR): written as stored, its values would be
// read back as linear light and show too bright and washed out.
cv::Mat to_linear_floats(const cv::Mat& data) {
  const int nc = data.channels(), colour = nc == 2 || nc == 4 ? nc - 1 : nc;
  cv::Mat out;  // continuous
  data.convertTo(out, CV_32F, data.depth() == CV_8U ? 1.0 / 255.0 : 1.0 / 65535.0);
  float* v = out.ptr<float>();
  for (std::size_t i = 0; i < out.total() * nc; ++i) {
    if (static_cast<int>(i % nc) < colour) v[i] = static_cast<float>(srgb_to_linear(v[i]));
  }
  return out;
}

std::string encode(const cv::Mat& image, const fs::path& file, const fs::path& name) {
  CV_Assert(image.depth() == CV_8U || image.depth() == CV_16U);
  // The plugin is chosen from the final name's extension, then opened on `file`.
  auto out = OIIO::ImageOutput::create(name.string());
  if (!out) throw Error(quoted(name) + ": cannot write this format (" + first_line(OIIO::geterror()) + ")");
  cv::Mat data = image.isContinuous() ? image : image.clone();
  // WebP holds no grey image (RGB and RGBA only) and refused it after the removal had run:
  // grey is written as RGB (its three channels equal), grey+alpha as RGBA, and said. Other
  // formats' refusals stand (their grey or alpha limits differ).
  std::string grey_lost;
  if ((data.channels() == 1 || data.channels() == 2) && std::string(out->format_name()) == "webp") {
    std::vector<cv::Mat> planes;
    cv::split(data, planes);
    std::vector<cv::Mat> colour = {planes[0], planes[0], planes[0]};
    if (planes.size() == 2) colour.push_back(planes[1]);
    cv::merge(colour, data);
    grey_lost = std::string("webp holds no grey image: written as ") + (planes.size() == 2 ? "RGBA" : "RGB");
  }
  OIIO::ImageSpec spec(data.cols, data.rows, data.channels(),
                       data.depth() == CV_8U ? OIIO::TypeDesc::UINT8 : OIIO::TypeDesc::UINT16);
  if (data.channels() == 4) spec.alpha_channel = 3;
  if (data.channels() == 4 || data.channels() == 2) spec.attribute("oiio:UnassociatedAlpha", 1);
  bool ok = out->open(file.string(), spec);
  // What the format cannot hold, known once its writer has opened: it lowers its own spec's
  // depth (BMP, WebP store 8 bits; OpenEXR 16-bit half floats hold about 11 bits), says whether
  // it stores alpha, and GIF keeps a palette of 256 colours.
  const OIIO::TypeDesc stored = ok ? out->spec().format : spec.format;
  const bool floats = ok && is_float(stored);
  const bool palette = ok && std::string(out->format_name()) == "gif";
  const std::string depth_lost = stored.size() < spec.format.size() ? "rounded to 8 bits"
                                 : floats && stored.basetype == OIIO::TypeDesc::HALF && data.depth() == CV_16U
                                     ? "stored as half floats (about 11 bits)"
                                     : "";
  std::string lost = ok ? format_loss(out->format_name(), static_cast<int>(spec.format.size() * 8), data.channels(),
                                      depth_lost, (data.channels() == 2 || data.channels() == 4) && !out->supports("alpha"))
                        : "";
  if (palette) lost += (lost.empty() ? "gif holds 256 colours: " : ", ") + std::string("colours quantised to a palette");
  if (!grey_lost.empty()) lost += (lost.empty() ? "" : "; ") + grey_lost;
  if (floats) {
    ok = ok && out->write_image(OIIO::TypeDesc::FLOAT, to_linear_floats(data).data);
  } else {
    ok = ok && out->write_image(spec.format, data.data);
  }
  ok = out->close() && ok;
  if (!ok) throw Error(quoted(name) + ": cannot write (" + first_line(out->geterror()) + ")");
  // OpenImageIO's JPEG 2000 writer here reports success and writes nothing: a 0-byte output
  // and exit 0 before this check.
  std::error_code ec;
  if (fs::file_size(file, ec) == 0 || ec)
    throw Error(quoted(name) + ": cannot write (the " + out->format_name() + " writer wrote no bytes)");
  return lost;
}

void check_writable_format(const fs::path& name) {
  if (!OIIO::ImageOutput::create(name.string()))
    throw Error(quoted(name) + ": cannot write this format (" + first_line(OIIO::geterror()) + ")");
}

const Codec kCodec = {kInterface, read_header, decode, encode, check_writable_format};

}  // namespace
}  // namespace raindrop::oiio

// The name is kEntryPoint (oiio_codec.h).
extern "C" __attribute__((visibility("default"))) const raindrop::oiio::Codec* raindrop_oiio_codec_v1() {
  return &raindrop::oiio::kCodec;
}
