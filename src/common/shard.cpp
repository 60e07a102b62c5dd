#include "raindrop/common/shard.h"

#include <cctype>
#include <cstdint>

#include "raindrop/common/error.h"
#include "raindrop/common/rng.h"

namespace raindrop {

bool Shard::owns(std::string_view name) const {
  return count <= 1 || hash_string(name) % static_cast<std::uint64_t>(count) == static_cast<std::uint64_t>(index);
}

std::string Shard::text() const { return std::to_string(index) + "/" + std::to_string(count); }

Shard parse_shard(const std::string& text) {
  const std::string usage = "--shard '" + text + "' must be K/N with 0 <= K < N (K 0-based, e.g. 0/4 to 3/4)";
  const auto slash = text.find('/');
  auto number = [&](const std::string& s) {
    if (s.empty() || s.size() > 9) throw Error(usage);
    for (char c : s) {
      if (!std::isdigit(static_cast<unsigned char>(c))) throw Error(usage);
    }
    return std::stoi(s);
  };
  if (slash == std::string::npos) throw Error(usage);
  Shard s;
  s.index = number(text.substr(0, slash));
  s.count = number(text.substr(slash + 1));
  if (s.count < 1 || s.index >= s.count) throw Error(usage);
  return s;
}

}  // namespace raindrop
