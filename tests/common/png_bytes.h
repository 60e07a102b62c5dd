#pragma once
// PNG files built and taken apart byte by byte, for tests that hand programs damaged or
// hand-made PNGs: chunks with correct CRCs, so that only what a test changes is wrong.
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace testsupport {

// CRC-32 (PNG's), for hand-made PNG headers.
inline std::uint32_t crc32(const std::string& bytes) {
  std::uint32_t c = 0xFFFFFFFFu;
  for (unsigned char b : bytes) {
    c ^= b;
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1u)));
  }
  return c ^ 0xFFFFFFFFu;
}

inline std::string be32(std::uint32_t v) {
  return std::string{static_cast<char>(v >> 24), static_cast<char>(v >> 16), static_cast<char>(v >> 8), static_cast<char>(v)};
}

inline std::string png_chunk(const std::string& type, const std::string& data) {
  return be32(static_cast<std::uint32_t>(data.size())) + type + data + be32(crc32(type + data));
}

// A PNG that declares width x height (8-bit RGB) but holds no pixel data.
inline std::string png_declaring(std::uint32_t width, std::uint32_t height) {
  const std::string sig = "\x89PNG\r\n\x1a\n";
  const std::string ihdr = be32(width) + be32(height) + std::string{8, 2, 0, 0, 0};
  // An IDAT (an empty zlib stream) so that libpng's header reading stops there cleanly.
  const std::string idat{'\x78', '\x9c', '\x03', '\x00', '\x00', '\x00', '\x00', '\x01'};
  return sig + png_chunk("IHDR", ihdr) + png_chunk("IDAT", idat) + png_chunk("IEND", "");
}

// A PNG's chunks in order: (type, data).
inline std::vector<std::pair<std::string, std::string>> png_chunks(const std::string& png) {
  std::vector<std::pair<std::string, std::string>> chunks;
  size_t at = 8;
  while (at + 12 <= png.size()) {
    const auto* b = reinterpret_cast<const unsigned char*>(png.data() + at);
    const std::uint32_t n = (std::uint32_t{b[0]} << 24) | (std::uint32_t{b[1]} << 16) | (std::uint32_t{b[2]} << 8) | b[3];
    chunks.emplace_back(png.substr(at + 4, 4), png.substr(at + 8, n));
    at += 12 + n;
  }
  return chunks;
}

// The PNG with the given chunks, CRCs recomputed (so that only the content is wrong).
inline std::string png_from_chunks(const std::vector<std::pair<std::string, std::string>>& chunks) {
  std::string png = "\x89PNG\r\n\x1a\n";
  for (const auto& [type, data] : chunks) png += png_chunk(type, data);
  return png;
}

}  // namespace testsupport
