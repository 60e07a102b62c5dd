// src/cli/options.h: the conventions every program's command line shares (sizes WxH, enums by
// name), checked through CLI11 itself.
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "../../src/cli/options.h"

namespace {

enum class Colour { red = 3, green = 7 };

// Parses `args` (without the program name) with one --colour and one --size option.
struct Parsed {
  bool ok = false;
  std::string error;
  Colour colour = Colour::red;
  std::string size;
};

Parsed parse(std::vector<std::string> args) {
  CLI::App app;
  Parsed p;
  app.add_option("--colour", p.colour)->transform(raindrop::cli::names_to(std::map<std::string, Colour>{
                                             {"red", Colour::red}, {"green", Colour::green}}));
  app.add_option("--size", p.size)->check(raindrop::cli::width_height(16, 4096));
  std::reverse(args.begin(), args.end());  // CLI11 takes the vector reversed
  try {
    app.parse(args);
    p.ok = true;
  } catch (const CLI::ParseError& e) {
    p.error = e.what();
  }
  return p;
}

}  // namespace

TEST(CliOptions, EnumsByNameOnly) {
  EXPECT_EQ(parse({"--colour", "green"}).colour, Colour::green);
  EXPECT_EQ(parse({"--colour", "red"}).colour, Colour::red);
  const auto number = parse({"--colour", "7"});  // the enum's value is not a name
  EXPECT_FALSE(number.ok);
  EXPECT_NE(number.error.find("'7' is not one of {green,red}"), std::string::npos) << number.error;
  EXPECT_FALSE(parse({"--colour", "Green"}).ok);
}

TEST(CliOptions, SizesAreWidthByHeight) {
  const auto s = raindrop::cli::parse_width_height("512x256");
  ASSERT_TRUE(s);
  EXPECT_EQ(s->width, 512);
  EXPECT_EQ(s->height, 256);
  for (const char* bad : {"512", "512x", "x256", "512x256x", "512X256", "-512x256", "512x256 ", "0x10", ""})
    EXPECT_FALSE(raindrop::cli::parse_width_height(bad)) << "'" << bad << "'";
  EXPECT_TRUE(parse({"--size", "4096x16"}).ok);
  EXPECT_FALSE(parse({"--size", "4097x16"}).ok);  // past the option's bounds
  EXPECT_FALSE(parse({"--size", "15x100"}).ok);
  EXPECT_FALSE(parse({"--size", ""}).ok);  // empty only where an option allows it
  const auto bad = parse({"--size", "256x512x"});
  EXPECT_FALSE(bad.ok);
  EXPECT_NE(bad.error.find("WIDTHxHEIGHT"), std::string::npos) << bad.error;
}

TEST(CliOptions, Unsigned64TakesExactlyTheRange) {
  const auto check = [](std::string text) { return raindrop::cli::unsigned_64("seeds")(text); };
  EXPECT_EQ(check("0"), "");
  EXPECT_EQ(check("42"), "");
  EXPECT_EQ(check("18446744073709551615"), "");  // 2^64 - 1
  for (const char* bad : {"18446744073709551616", "99999999999999999999", "-1", "-0", "+1", "1.0", "1e3", "0x10", " 1",
                          "1 ", ""}) {
    const std::string why = check(bad);
    EXPECT_NE(why, "") << "'" << bad << "' was accepted";
    EXPECT_NE(why.find("2^64 - 1"), std::string::npos) << why;
  }
}
