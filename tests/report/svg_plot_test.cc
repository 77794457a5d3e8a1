// The report's SVG plots (src/rodfit/report/svg_plot.h): tick choice, tick labels, escaping of
// every text, finite-only drawing, the explicit "no data" figure, equal aspect, and that every
// rendered figure is well-formed XML.
#include "rodfit/report/svg_plot.h"

#include <cmath>
#include <random>
#include <regex>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace rodfit::svg {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

// Checks that `xml` is one well-formed element: every tag closed in order, attributes quoted,
// no stray '<' or '&' in text. Returns "" or what is wrong.
std::string WellFormed(const std::string& xml) {
  std::vector<std::string> open;
  size_t i = 0;
  int roots = 0;
  while (i < xml.size()) {
    if (xml[i] == '<') {
      const size_t end = xml.find('>', i);
      if (end == std::string::npos) return "unclosed tag at " + std::to_string(i);
      std::string tag = xml.substr(i + 1, end - i - 1);
      if (tag.find('<') != std::string::npos) return "'<' inside a tag at " + std::to_string(i);
      // Attribute values must be quoted and contain no raw '<' or unescaped '&'.
      const std::regex bad_amp("&(?!(amp|lt|gt|quot|#39);)");
      if (std::regex_search(tag, bad_amp)) return "raw '&' in tag " + tag.substr(0, 40);
      if (tag[0] == '/') {
        const std::string name = tag.substr(1);
        if (open.empty() || open.back() != name) return "mismatched </" + name + ">";
        open.pop_back();
      } else if (tag.back() != '/') {
        const std::string name = tag.substr(0, tag.find_first_of(" \n\t"));
        if (open.empty()) ++roots;
        open.push_back(name);
      } else if (open.empty()) {
        ++roots;
      }
      i = end + 1;
    } else {
      if (xml[i] == '&') {
        const std::regex entity("^&(amp|lt|gt|quot|#39);");
        if (!std::regex_search(xml.substr(i, 8), entity)) return "raw '&' in text";
      } else if (xml[i] == '>') {
        return "raw '>' in text";
      }
      ++i;
    }
  }
  if (!open.empty()) return "unclosed <" + open.back() + ">";
  if (roots != 1) return "expected one root element, found " + std::to_string(roots);
  return "";
}

Figure LineFigure(std::vector<double> x, std::vector<double> y) {
  Figure f;
  f.title = "a line";
  f.x.label = "t [s]";
  f.y.label = "force [N]";
  Series s;
  s.label = "measured";
  s.x = std::move(x);
  s.y = std::move(y);
  f.series.push_back(s);
  return f;
}

// The numbers in a path's d attribute, in order.
std::vector<double> PathNumbers(const std::string& d) {
  std::vector<double> out;
  const std::regex number("-?[0-9]+(\\.[0-9]+)?");
  for (auto it = std::sregex_iterator(d.begin(), d.end(), number); it != std::sregex_iterator();
       ++it)
    out.push_back(std::stod(it->str()));
  return out;
}

// The d attributes of the paths drawn for series (inside <g class="series" ...>).
std::vector<std::string> SeriesPaths(const std::string& svg) {
  std::vector<std::string> out;
  const std::regex path("<g class=\"series\"[^>]*><path d=\"([^\"]*)\"");
  for (auto it = std::sregex_iterator(svg.begin(), svg.end(), path); it != std::sregex_iterator();
       ++it)
    out.push_back((*it)[1]);
  return out;
}

TEST(SvgTicks, StepIsOneTwoOrFiveTimesAPowerOfTenAndTicksLieInside) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> exponent(-9, 9), unit(-1, 1);
  for (int trial = 0; trial < 2000; ++trial) {
    const double scale = std::pow(10.0, exponent(rng));
    double lo = unit(rng) * scale, hi = unit(rng) * scale;
    if (lo > hi) std::swap(lo, hi);
    if (!(hi > lo)) continue;
    for (int target : {3, 6, 10}) {
      const double step = TickStep(lo, hi, target);
      const double mantissa = step / std::pow(10.0, std::floor(std::log10(step) + 1e-12));
      EXPECT_TRUE(std::abs(mantissa - 1) < 1e-9 || std::abs(mantissa - 2) < 1e-9 ||
                  std::abs(mantissa - 5) < 1e-9 || std::abs(mantissa - 10) < 1e-9)
          << "step " << step << " for [" << lo << ", " << hi << "]";
      const std::vector<double> ticks = LinearTicks(lo, hi, target);
      // At least 2 ticks; at most about target * 1.25 (the step rounds down by at most 1.25).
      EXPECT_GE(ticks.size(), 2u) << lo << " " << hi << " target " << target;
      EXPECT_LE(ticks.size(), static_cast<size_t>(std::ceil(1.25 * target)) + 1)
          << lo << " " << hi << " target " << target;
      for (double t : ticks) {
        EXPECT_GE(t, lo - 1e-9 * step);
        EXPECT_LE(t, hi + 1e-9 * step);
        EXPECT_NEAR(t / step, std::round(t / step), 1e-6) << t << " is not a multiple of " << step;
      }
    }
  }
}

TEST(SvgTicks, KnownRanges) {
  EXPECT_DOUBLE_EQ(TickStep(0, 10, 5), 2.0);
  EXPECT_DOUBLE_EQ(TickStep(0, 1, 5), 0.2);
  EXPECT_DOUBLE_EQ(TickStep(-3, 3, 6), 1.0);
  EXPECT_EQ(LinearTicks(-3, 3, 6), (std::vector<double>{-3, -2, -1, 0, 1, 2, 3}));
  // A range that straddles zero has an exact 0 tick (not 1e-17).
  for (double t : LinearTicks(-0.3, 0.7, 5)) {
    if (std::abs(t) < 0.05) {
      EXPECT_EQ(t, 0.0);
    }
  }
}

TEST(SvgTicks, NonFiniteOrEmptyRangesGiveNoTicks) {
  EXPECT_TRUE(std::isnan(TickStep(NAN, 1)));
  EXPECT_TRUE(std::isnan(TickStep(0, INFINITY)));
  EXPECT_TRUE(std::isnan(TickStep(1, 1)));
  EXPECT_TRUE(LinearTicks(2, 1).empty());
  EXPECT_TRUE(LogTicks(0, 10).empty());
  EXPECT_TRUE(LogTicks(-1, 10).empty());
}

TEST(SvgTicks, LogTicksArePowersOfTenThinnedToTheTarget) {
  const std::vector<double> ticks = LogTicks(1e-3, 1e3, 6);
  ASSERT_GE(ticks.size(), 2u);
  EXPECT_LE(ticks.size(), 6u);
  for (double t : ticks) EXPECT_NEAR(std::log10(t), std::round(std::log10(t)), 1e-12);
  // Within one decade: 1, 2, 5 multiples.
  EXPECT_EQ(LogTicks(1.5, 12, 6), (std::vector<double>{2, 5, 10}));
}

TEST(SvgTicks, LabelsHaveTheDecimalsTheStepNeeds) {
  EXPECT_EQ(FormatTick(0.05, 0.05), "0.05");
  EXPECT_EQ(FormatTick(0.1, 0.05), "0.10");
  EXPECT_EQ(FormatTick(1500, 500), "1500");
  EXPECT_EQ(FormatTick(-3, 1), "-3");
  EXPECT_EQ(FormatTick(1e-17, 0.1), "0");  // rounding residue of a zero tick
  EXPECT_EQ(FormatTick(2e-7, 1e-7), "2e-7");
  EXPECT_EQ(FormatTick(2.5e-7, 5e-8), "2.5e-7");
  EXPECT_EQ(FormatTick(3e6, 1e6), "3e6");
}

TEST(SvgText, EscapesMarkupCharacters) {
  EXPECT_EQ(Escape("<a & 'b'>\""), "&lt;a &amp; &#39;b&#39;&gt;&quot;");
  EXPECT_EQ(Escape("plain text [mm]"), "plain text [mm]");
}

TEST(SvgRender, EveryTextIsEscaped) {
  Figure f = LineFigure({0, 1, 2}, {1, 3, 2});
  f.title = "case <script>alert('x')</script> & co";
  f.x.label = "u <px>";
  f.series[0].label = "entry \"a&b\"";
  f.series[0].point_labels = {"<s>", "", "s = 0.1 m"};
  f.bands.push_back({-1, 1, "#00ff00", 0.2, "band <1>"});
  const std::string svg = RenderSvg(f, "fig-1");
  EXPECT_EQ(WellFormed(svg), "");
  EXPECT_THAT(svg, Not(HasSubstr("<script>")));
  EXPECT_THAT(svg, HasSubstr("case &lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt; &amp; co"));
  EXPECT_THAT(svg, HasSubstr("u &lt;px&gt;"));
  EXPECT_THAT(svg, HasSubstr("entry &quot;a&amp;b&quot;"));
  EXPECT_THAT(svg, HasSubstr("&lt;s&gt;"));
  EXPECT_THAT(svg, HasSubstr("band &lt;1&gt;"));
}

TEST(SvgRender, AxesLegendAndTicksAreDrawn) {
  const std::string svg = RenderSvg(LineFigure({0, 1, 2, 3}, {0, 10, 20, 30}), "f");
  EXPECT_EQ(WellFormed(svg), "");
  EXPECT_THAT(svg, HasSubstr("xmlns=\"http://www.w3.org/2000/svg\""));
  EXPECT_THAT(svg, HasSubstr(">t [s]</text>"));
  EXPECT_THAT(svg, HasSubstr(">force [N]</text>"));
  EXPECT_THAT(svg, HasSubstr("class=\"legend\""));
  EXPECT_THAT(svg, HasSubstr(">measured</text>"));
  EXPECT_THAT(svg, HasSubstr(">20</text>"));  // a y tick label
  EXPECT_THAT(svg, Not(HasSubstr("no-data")));
  // Fonts are at least 12 px.
  const std::regex font("font-size=\"([0-9]+)\"");
  for (auto it = std::sregex_iterator(svg.begin(), svg.end(), font); it != std::sregex_iterator();
       ++it)
    EXPECT_GE(std::stoi((*it)[1]), 12);
}

TEST(SvgRender, OnlyFiniteDataAreDrawnAndLinesBreakAtGaps) {
  const std::string svg =
      RenderSvg(LineFigure({0, 1, 2, 3, 4, 5}, {1, 2, NAN, 3, INFINITY, 4}), "f");
  EXPECT_EQ(WellFormed(svg), "");
  EXPECT_THAT(svg, Not(::testing::ContainsRegex("[Nn]a[Nn]|inf")));
  const std::vector<std::string> paths = SeriesPaths(svg);
  ASSERT_EQ(paths.size(), 1u);
  // Points 0-1, then 3 alone, then 5 alone: three sub-paths (M), two segments (L) in all.
  EXPECT_EQ(std::count(paths[0].begin(), paths[0].end(), 'M'), 3);
  EXPECT_EQ(std::count(paths[0].begin(), paths[0].end(), 'L'), 1);
}

TEST(SvgRender, LogAxisDropsValuesThatAreNotPositive) {
  Figure f = LineFigure({0, 1, 2, 3}, {100, 0, -5, 1});
  f.y.log = true;
  const std::string svg = RenderSvg(f, "f");
  EXPECT_EQ(WellFormed(svg), "");
  const std::vector<std::string> paths = SeriesPaths(svg);
  ASSERT_EQ(paths.size(), 1u);
  EXPECT_EQ(std::count(paths[0].begin(), paths[0].end(), 'M'), 2);  // 100 and 1 only
  EXPECT_THAT(svg, HasSubstr(">10\u00b2</text>"));                    // a power-of-ten label
}

TEST(SvgRender, EmptyOrNonFiniteDataGiveAnExplicitNoDataFigure) {
  for (const Figure& f : {LineFigure({}, {}), LineFigure({NAN, 1}, {2, INFINITY})}) {
    EXPECT_FALSE(HasData(f));
    const std::string svg = RenderSvg(f, "f");
    EXPECT_EQ(WellFormed(svg), "");
    EXPECT_THAT(svg, HasSubstr("class=\"no-data\""));
    EXPECT_THAT(svg, HasSubstr(">no data</text>"));
    EXPECT_THAT(svg, HasSubstr(">t [s]</text>"));  // still says what it would show
    EXPECT_TRUE(SeriesPaths(svg).empty());
  }
  Figure none;
  none.title = "nothing at all";
  EXPECT_EQ(WellFormed(RenderSvg(none, "x")), "");
}

TEST(SvgRender, EqualAspectDrawsAUnitSquareAsASquare) {
  Figure f = LineFigure({0, 10, 10, 0}, {0, 0, 1, 1});  // 10 x 1 data units
  f.equal_aspect = true;
  f.series[0].closed = true;
  const std::vector<std::string> paths = SeriesPaths(RenderSvg(f, "f"));
  ASSERT_EQ(paths.size(), 1u);
  const std::vector<double> n = PathNumbers(paths[0]);
  ASSERT_EQ(n.size(), 8u);
  const double width_px = std::abs(n[2] - n[0]), height_px = std::abs(n[5] - n[3]);
  EXPECT_NEAR(width_px / height_px, 10.0, 0.01);
  EXPECT_EQ(paths[0].back(), 'Z');
}

TEST(SvgRender, OverlappingPointLabelsAreLeftOut) {
  Figure f = LineFigure({0, 0.001, 10}, {0, 0.001, 10});  // the first two points coincide
  f.series[0].point_labels = {"s = 0.1 m", "s = 0.2 m", "s = 0.3 m"};
  const std::string svg = RenderSvg(f, "f");
  EXPECT_THAT(svg, HasSubstr(">s = 0.1 m</text>"));
  EXPECT_THAT(svg, Not(HasSubstr(">s = 0.2 m</text>")));
  EXPECT_THAT(svg, HasSubstr(">s = 0.3 m</text>"));
}

TEST(SvgRender, BarsAndBandsAreDrawnInsideThePlot) {
  Figure f;
  f.x.label = "residual [σ]";
  f.y.label = "count";
  Series bars;
  bars.label = "histogram";
  bars.bars = true;
  bars.line = false;
  bars.bar_width = 0.5;
  bars.x = {-0.25, 0.25};
  bars.y = {3, 5};
  f.series.push_back(bars);
  f.bands.push_back({-1, 1, "#2ca02c", 0.2, "±1 σ"});
  const std::string svg = RenderSvg(f, "hist");
  EXPECT_EQ(WellFormed(svg), "");
  EXPECT_THAT(svg, HasSubstr("class=\"band\""));
  EXPECT_THAT(svg, HasSubstr(">±1 σ</text>"));
  EXPECT_THAT(svg, HasSubstr("clip-path=\"url(#hist-clip)\""));
}

}  // namespace
}  // namespace rodfit::svg
