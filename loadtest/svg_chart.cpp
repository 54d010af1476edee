#include "loadtest/svg_chart.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ostream>

namespace vox::loadtest {

namespace {

constexpr double kWidth = 920, kLeft = 80, kRight = 190;  // the legend sits right of the plot
constexpr double kHeadingH = 36, kTitleH = 30, kPlotH = 200, kAxisH = 46;
constexpr double kPanelH = kTitleH + kPlotH + kAxisH;
constexpr const char* kFont = "font-family=\"sans-serif\"";

std::string fixed(double v, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

// "1234567" -> "1,234,567"
std::string with_commas(long long v) {
  std::string digits = std::to_string(v < 0 ? -v : v), out;
  for (size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return v < 0 ? "-" + out : out;
}

std::string escape(const std::string& text) {
  std::string out;
  for (const char c : text) {
    switch (c) {
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '&':
        out += "&amp;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

struct Frame {  // one panel's plot area and its mapping of values to pixels
  double x0, x1, y0, y1;
  const ChartPanel* p;
  double y_top;  // the value at the top of the plot

  double px(double x) const {
    const double span = p->x_max > p->x_min ? p->x_max - p->x_min : 1;
    return x0 + (x - p->x_min) / span * (x1 - x0);
  }
  double py(double y) const {
    double f = 0;
    if (p->log_y) {
      const double lo = std::log10(p->y_floor), hi = std::log10(y_top);
      f = (std::log10(std::max(y, p->y_floor)) - lo) / std::max(1e-9, hi - lo);
    } else {
      f = y / std::max(1e-12, y_top);
    }
    return y1 - std::clamp(f, 0.0, 1.05) * (y1 - y0);
  }
};

double largest_value(const ChartPanel& p) {
  double top = 0;
  for (const auto& s : p.series)
    for (const auto& pt : s.points) top = std::max(top, pt.second);
  if (p.goal) top = std::max(top, p.goal->first);
  return top;
}

std::vector<double> y_ticks(const ChartPanel& p, double& y_top) {
  const double top = p.y_max.value_or(largest_value(p));
  if (p.log_y) {
    y_top = std::pow(10, std::ceil(std::log10(std::max(top, p.y_floor * 10)) - 1e-9));
    std::vector<double> ticks;
    const bool minor = std::log10(y_top / p.y_floor) <= 3.01;
    for (double d = p.y_floor; d <= y_top * 1.0001; d *= 10) {
      ticks.push_back(d);
      if (minor && d * 2 < y_top) ticks.push_back(d * 2);
      if (minor && d * 5 < y_top) ticks.push_back(d * 5);
    }
    return ticks;
  }
  // Headroom above the data; an all-zero panel (an idle server, no edits) spans 0..1.
  const double wanted = top > 0 ? top * (p.y_max ? 1.0 : 1.08) : 1;
  auto ticks = nice_ticks(0, wanted);
  if (ticks.size() > 1 && ticks.back() < wanted * 0.999)  // one more round tick above the data
    ticks.push_back(nice_ticks(0, ticks.back() + (ticks[1] - ticks[0]), 6).back());
  y_top = p.y_max.value_or(ticks.back());
  return ticks;
}

void write_axes(const Frame& f, const std::vector<double>& yt, std::ostream& out) {
  const ChartPanel& p = *f.p;
  for (const double y : yt) {
    const double py = f.py(y);
    out << "<line x1=\"" << f.x0 << "\" y1=\"" << py << "\" x2=\"" << f.x1 << "\" y2=\"" << py
        << "\" stroke=\"#e0e0e0\"/>\n<text x=\"" << f.x0 - 6 << "\" y=\"" << py + 4 << "\" "
        << kFont << " font-size=\"11\" text-anchor=\"end\">" << human_number(y) << "</text>\n";
  }
  for (const double x : nice_ticks(p.x_min / p.x_scale, p.x_max / p.x_scale, 8)) {
    const double px = f.px(x * p.x_scale);
    out << "<line x1=\"" << px << "\" y1=\"" << f.y1 << "\" x2=\"" << px << "\" y2=\"" << f.y1 + 5
        << "\" stroke=\"black\"/>\n<text x=\"" << px << "\" y=\"" << f.y1 + 18 << "\" " << kFont
        << " font-size=\"11\" text-anchor=\"middle\">" << human_number(x) << "</text>\n";
  }
  out << "<path d=\"M" << f.x0 << "," << f.y0 << " V" << f.y1 << " H" << f.x1
      << "\" fill=\"none\" stroke=\"black\"/>\n<text x=\"" << (f.x0 + f.x1) / 2 << "\" y=\""
      << f.y1 + 36 << "\" " << kFont << " font-size=\"12\" text-anchor=\"middle\">"
      << escape(p.x_label) << "</text>\n<text transform=\"translate(" << f.x0 - 52 << ","
      << (f.y0 + f.y1) / 2 << ") rotate(-90)\" " << kFont
      << " font-size=\"12\" text-anchor=\"middle\">" << escape(p.y_label) << "</text>\n";
}

void write_series(const Frame& f, const ChartSeries& s, std::ostream& out) {
  if (s.points.empty()) return;
  out << "<path fill=\"none\" stroke=\"" << s.colour << "\" stroke-width=\"" << s.width
      << "\" stroke-linejoin=\"round\" d=\"";
  for (size_t i = 0; i < s.points.size(); ++i) {
    const double x = f.px(s.points[i].first), y = f.py(s.points[i].second);
    if (i == 0) {
      out << "M" << fixed(x, 1) << "," << fixed(y, 1);
    } else if (s.step) {
      out << " H" << fixed(x, 1) << " V" << fixed(y, 1);
    } else {
      out << " L" << fixed(x, 1) << "," << fixed(y, 1);
    }
  }
  out << "\"/>\n";
  if (!s.markers) return;
  for (const auto& [x, y] : s.points) {
    out << "<circle cx=\"" << f.px(x) << "\" cy=\"" << f.py(y) << "\" r=\"4\" fill=\"" << s.colour
        << "\"/><text x=\"" << f.px(x) << "\" y=\"" << f.py(y) - 8 << "\" " << kFont
        << " font-size=\"11\" text-anchor=\"middle\">" << human_number(y) << "</text>\n";
  }
}

void write_legend(const Frame& f, std::ostream& out) {
  const ChartPanel& p = *f.p;
  double y = f.y0 + 8;
  auto entry = [&](const std::string& colour, const std::string& name, bool dashed) {
    out << "<line x1=\"" << f.x1 + 14 << "\" y1=\"" << y << "\" x2=\"" << f.x1 + 36 << "\" y2=\""
        << y << "\" stroke=\"" << colour << "\" stroke-width=\"2\""
        << (dashed ? " stroke-dasharray=\"6 4\"" : "") << "/><text x=\"" << f.x1 + 42 << "\" y=\""
        << y + 4 << "\" " << kFont << " font-size=\"11\">" << escape(name) << "</text>\n";
    y += 18;
  };
  for (const auto& s : p.series) entry(s.colour, s.name, false);
  if (p.goal) entry("#c02020", p.goal->second, true);
}

void write_panel(const ChartPanel& p, double top, int index, std::ostream& out) {
  Frame f{kLeft, kWidth - kRight, top + kTitleH, top + kTitleH + kPlotH, &p, 1};
  const auto yt = y_ticks(p, f.y_top);
  out << "<text x=\"" << kLeft << "\" y=\"" << top + 20 << "\" " << kFont
      << " font-size=\"14\" font-weight=\"bold\">" << escape(p.title) << "</text>\n";
  for (const auto& [a, b] : p.bands) {
    out << "<rect x=\"" << f.px(a) << "\" y=\"" << f.y0 << "\" width=\"" << f.px(b) - f.px(a)
        << "\" height=\"" << kPlotH << "\" fill=\"#f2f2f2\"/>\n";
  }
  write_axes(f, yt, out);
  out << "<clipPath id=\"plot" << index << "\"><rect x=\"" << f.x0 << "\" y=\"" << f.y0 - 2
      << "\" width=\"" << f.x1 - f.x0 + 2 << "\" height=\"" << kPlotH + 4
      << "\"/></clipPath>\n<g clip-path=\"url(#plot" << index << ")\">\n";
  for (const auto& s : p.series) write_series(f, s, out);
  if (p.goal) {
    out << "<line x1=\"" << f.x0 << "\" y1=\"" << f.py(p.goal->first) << "\" x2=\"" << f.x1
        << "\" y2=\"" << f.py(p.goal->first)
        << "\" stroke=\"#c02020\" stroke-width=\"1.5\" stroke-dasharray=\"6 4\"/>\n";
  }
  out << "</g>\n";
  write_legend(f, out);
}

}  // namespace

std::vector<double> nice_ticks(double lo, double hi, int target) {
  if (!(hi > lo)) return {lo};
  const double raw = (hi - lo) / std::max(1, target);
  const double magnitude = std::pow(10, std::floor(std::log10(raw)));
  double m = 10;
  for (const double candidate : {1.0, 2.0, 2.5, 5.0}) {
    if (candidate * magnitude >= raw * 0.999) {
      m = candidate;
      break;
    }
  }
  // Tick k is k * m * magnitude, computed so that 3 * 0.2 gives 0.6, not 0.6000000000000001.
  const double inverse = magnitude < 1 ? std::round(1 / magnitude) : 0;
  auto value = [&](double k) { return inverse > 0 ? k * m / inverse : k * m * magnitude; };
  const double step = value(1);
  std::vector<double> ticks;
  for (double k = std::ceil(lo / step - 1e-9); value(k) <= hi + step * 1e-6; k += 1)
    ticks.push_back(k == 0 ? 0 : value(k));
  return ticks;
}

std::string human_number(double v) {
  const double a = std::abs(v);
  if (a >= 1e6) return fixed(v / 1e6, a >= 1e8 ? 0 : 1) + " M";
  if (a >= 1000) return with_commas(std::llround(v));
  if (a == std::floor(a)) return fixed(v, 0);
  // Below 1: two significant digits at least (0.25, 0.125, 0.0002), not "0".
  const int small = static_cast<int>(std::ceil(-std::log10(a))) + 2;
  std::string s = fixed(v, a >= 100 ? 0 : a >= 10 ? 1 : a >= 1 ? 2 : std::min(small, 12));
  while (s.find('.') != std::string::npos && (s.back() == '0' || s.back() == '.')) {
    const bool dot = s.back() == '.';
    s.pop_back();
    if (dot) break;
  }
  return s;
}

void write_chart(const std::string& heading, const std::vector<ChartPanel>& panels,
                 std::ostream& out) {
  const double height = kHeadingH + kPanelH * static_cast<double>(panels.size()) + 10;
  out << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << kWidth << "\" height=\"" << height
      << "\" viewBox=\"0 0 " << kWidth << " " << height << "\">\n"
      << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n<text x=\"" << kLeft
      << "\" y=\"24\" " << kFont << " font-size=\"15\">" << escape(heading) << "</text>\n";
  for (size_t i = 0; i < panels.size(); ++i)
    write_panel(panels[i], kHeadingH + kPanelH * static_cast<double>(i), static_cast<int>(i), out);
  out << "</svg>\n";
}

}  // namespace vox::loadtest
