#include "jpeg_file.h"

#include <csetjmp>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <cerrno>
#include <string>

// jpeglib.h needs size_t and FILE declared before it.
#include <jerror.h>
#include <jpeglib.h>

#include "exif_orientation.h"
#include "raindrop/common/error.h"

namespace raindrop::jpeg {
namespace fs = std::filesystem;
namespace {

// libjpeg reports through these instead of printing: an error keeps its message and returns to
// the setjmp of the call; a warning that means lost pixels is kept as the error to report.
struct ErrorSink {
  jpeg_error_mgr manager;
  std::jmp_buf jump;
  char message[JMSG_LENGTH_MAX] = "";
  bool damaged = false;
};

[[noreturn]] void on_error(j_common_ptr info) {
  auto* sink = reinterpret_cast<ErrorSink*>(info->err);
  const int os_error = errno;  // a failed fwrite's cause, which libjpeg's message leaves out
  (*info->err->format_message)(info, sink->message);
  if (info->err->msg_code == JERR_FILE_WRITE && os_error != 0)
    std::snprintf(sink->message, sizeof sink->message, "%s", std::strerror(os_error));
  std::longjmp(sink->jump, 1);
}

void on_message(j_common_ptr info, int level) {
  auto* sink = reinterpret_cast<ErrorSink*>(info->err);
  // level -1: a warning about the data. Extraneous bytes before a marker lose nothing.
  if (level >= 0 || info->err->msg_code == JWRN_EXTRANEOUS_DATA || sink->damaged) return;
  (*info->err->format_message)(info, sink->message);
  sink->damaged = true;
}

void install(ErrorSink& sink) {
  jpeg_std_error(&sink.manager);
  sink.manager.error_exit = on_error;
  sink.manager.emit_message = on_message;
  sink.manager.output_message = [](j_common_ptr) {};
}

// Keeps the APP1 markers through jpeg_read_header, where the EXIF Orientation is.
void keep_exif(jpeg_decompress_struct& d) { jpeg_save_markers(&d, JPEG_APP0 + 1, 0xFFFF); }

// The Orientation of the first EXIF APP1 marker that has one (exif_orientation.h; other APP1
// markers, such as XMP, are passed over), 1 without one.
int orientation_of(const jpeg_decompress_struct& d) {
  for (jpeg_saved_marker_ptr m = d.marker_list; m; m = m->next) {
    if (m->marker != JPEG_APP0 + 1) continue;
    if (const int o = exif::orientation(m->data, m->data_length)) return o;
  }
  return 1;
}

bool native_colour(const jpeg_decompress_struct& d) {
  return (d.num_components == 1 && d.jpeg_color_space == JCS_GRAYSCALE) ||
         (d.num_components == 3 && (d.jpeg_color_space == JCS_YCbCr || d.jpeg_color_space == JCS_RGB));
}

// Decodes from a source that `attach` sets up; `what` names it in errors.
template <typename Attach>
cv::Mat decode_from(Attach attach, const std::string& what, std::string* icc = nullptr) {
  ErrorSink sink;
  jpeg_decompress_struct d{};
  d.err = &sink.manager;
  install(sink);
  cv::Mat image;  // before setjmp: a longjmp skips no C++ frame
  volatile bool created = false;
  volatile int orientation = 1;
  if (setjmp(sink.jump) == 0) {
    jpeg_create_decompress(&d);
    created = true;
    attach(d);
    keep_exif(d);
    if (icc) jpeg_save_markers(&d, JPEG_APP0 + 2, 0xFFFF);  // where an ICC profile is
    jpeg_read_header(&d, TRUE);
    orientation = orientation_of(d);
    if (icc) {
      JOCTET* profile = nullptr;
      unsigned int length = 0;
      if (jpeg_read_icc_profile(&d, &profile, &length) && profile) icc->assign(reinterpret_cast<char*>(profile), length);
      std::free(profile);
    }
    if (!native_colour(d)) ERREXIT(&d, JERR_CONVERSION_NOTIMPL);
    d.out_color_space = d.num_components == 1 ? JCS_GRAYSCALE : JCS_RGB;
    jpeg_start_decompress(&d);
    image.create(static_cast<int>(d.output_height), static_cast<int>(d.output_width), CV_8UC(d.output_components));
    while (d.output_scanline < d.output_height) {
      JSAMPROW row = image.ptr(static_cast<int>(d.output_scanline));
      jpeg_read_scanlines(&d, &row, 1);
    }
    jpeg_finish_decompress(&d);
  } else {
    sink.damaged = true;
  }
  if (created) jpeg_destroy_decompress(&d);
  if (sink.damaged) throw Error(what + ": cannot decode (" + sink.message + ")");
  exif::make_upright(image, orientation);
  return image;
}

template <typename Attach>
void encode_to(const cv::Mat& image, int quality, Attach attach, const std::string& what, const std::string& icc = {}) {
  CV_Assert(image.type() == CV_8UC1 || image.type() == CV_8UC3);
  ErrorSink sink;
  jpeg_compress_struct c{};
  c.err = &sink.manager;
  install(sink);
  volatile bool created = false, ok = false;
  if (setjmp(sink.jump) == 0) {
    jpeg_create_compress(&c);
    created = true;
    attach(c);
    c.image_width = static_cast<JDIMENSION>(image.cols);
    c.image_height = static_cast<JDIMENSION>(image.rows);
    c.input_components = image.channels();
    c.in_color_space = image.channels() == 1 ? JCS_GRAYSCALE : JCS_RGB;
    jpeg_set_defaults(&c);  // standard tables, 4:2:0 chroma, as OpenImageIO writes
    jpeg_set_quality(&c, quality, TRUE);
    jpeg_start_compress(&c, TRUE);
    if (!icc.empty())
      jpeg_write_icc_profile(&c, reinterpret_cast<const JOCTET*>(icc.data()), static_cast<unsigned int>(icc.size()));
    while (c.next_scanline < c.image_height) {
      JSAMPROW row = const_cast<JSAMPROW>(image.ptr(static_cast<int>(c.next_scanline)));
      jpeg_write_scanlines(&c, &row, 1);
    }
    jpeg_finish_compress(&c);
    ok = true;
  }
  if (created) jpeg_destroy_compress(&c);
  if (!ok) throw Error(what + ": cannot write (" + sink.message + ")");
}

}  // namespace

bool has_signature(const unsigned char* first3) {
  return first3[0] == 0xFF && first3[1] == 0xD8 && first3[2] == 0xFF;
}

Info read_info(const fs::path& path) {
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (!file) throw Error(quoted(path) + ": cannot open (" + std::strerror(errno) + ")");
  ErrorSink sink;
  jpeg_decompress_struct d{};
  d.err = &sink.manager;
  install(sink);
  Info info;
  volatile bool created = false, ok = false;
  if (setjmp(sink.jump) == 0) {
    jpeg_create_decompress(&d);
    created = true;
    jpeg_stdio_src(&d, file);
    keep_exif(d);
    jpeg_read_header(&d, TRUE);
    const bool swapped = exif::swaps_sides(orientation_of(d));
    info.width = static_cast<int>(swapped ? d.image_height : d.image_width);
    info.height = static_cast<int>(swapped ? d.image_width : d.image_height);
    info.native = native_colour(d);
    info.channels = d.num_components == 1 ? 1 : 3;
    ok = true;
  }
  if (created) jpeg_destroy_decompress(&d);
  std::fclose(file);
  if (!ok) throw Error(quoted(path) + ": not a readable image (" + sink.message + ")");
  return info;
}

cv::Mat decode(const fs::path& path, std::string* icc) {
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (!file) throw Error(quoted(path) + ": cannot open (" + std::strerror(errno) + ")");
  try {
    cv::Mat image = decode_from([file](jpeg_decompress_struct& d) { jpeg_stdio_src(&d, file); }, quoted(path), icc);
    std::fclose(file);
    return image;
  } catch (...) {
    std::fclose(file);
    throw;
  }
}

cv::Mat decode(const std::vector<unsigned char>& bytes) {
  return decode_from([&bytes](jpeg_decompress_struct& d) { jpeg_mem_src(&d, bytes.data(), bytes.size()); },
                     "JPEG in memory");
}

void encode(const cv::Mat& image, std::FILE* file, int quality, const fs::path& name, const std::string& icc) {
  encode_to(image, quality, [file](jpeg_compress_struct& c) { jpeg_stdio_dest(&c, file); }, quoted(name), icc);
}

namespace {

// A libjpeg destination that appends to a vector. (jpeg_mem_dest's buffer pointer goes stale
// when the library grows it, so freeing it after an error mid-encode would free memory twice.)
struct VectorDestination {
  jpeg_destination_mgr manager{};
  std::vector<unsigned char>* bytes = nullptr;
  unsigned char block[16384];

  static VectorDestination& of(j_compress_ptr c) { return *reinterpret_cast<VectorDestination*>(c->dest); }
  static void append(j_compress_ptr c, size_t n) {
    VectorDestination& d = of(c);
    bool failed = false;
    try {
      d.bytes->insert(d.bytes->end(), d.block, d.block + n);
    } catch (...) {
      failed = true;
    }
    // An error through libjpeg's own path (a longjmp), not an exception through C frames; and
    // outside the catch block, which a longjmp must not leave.
    if (failed) ERREXIT1(c, JERR_OUT_OF_MEMORY, 0);
  }
  static void init(j_compress_ptr c) {
    of(c).manager.next_output_byte = of(c).block;
    of(c).manager.free_in_buffer = sizeof of(c).block;
  }
  static boolean empty(j_compress_ptr c) {
    append(c, sizeof of(c).block);
    init(c);
    return TRUE;
  }
  static void term(j_compress_ptr c) { append(c, sizeof of(c).block - of(c).manager.free_in_buffer); }
};

}  // namespace

std::vector<unsigned char> encode(const cv::Mat& image, int quality) {
  std::vector<unsigned char> bytes;
  VectorDestination destination;
  destination.bytes = &bytes;
  destination.manager.init_destination = VectorDestination::init;
  destination.manager.empty_output_buffer = VectorDestination::empty;
  destination.manager.term_destination = VectorDestination::term;
  encode_to(image, quality, [&](jpeg_compress_struct& c) { c.dest = &destination.manager; }, "JPEG in memory");
  return bytes;
}

}  // namespace raindrop::jpeg
