// Times OpenCV's planar pose on the corner dataset written by
// `cargo run --release --example corner_accuracy` (target/accuracy/corners.csv).
// Built and run by scripts/bench_opencv_pose.sh; prints one line per method:
// "<method> <median ns per call> <calls per round>".
#include <opencv2/calib3d.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

struct Case {
    std::vector<cv::Point2d> corners;  // qr order: TL, TR, BR, BL
};

static std::map<std::string, double> parse_header(const std::string& line) {
    std::map<std::string, double> out;
    std::istringstream in(line.substr(1));
    std::string kv;
    while (in >> kv) {
        auto eq = kv.find('=');
        if (eq != std::string::npos) out[kv.substr(0, eq)] = std::stod(kv.substr(eq + 1));
    }
    return out;
}

int main(int argc, char** argv) {
    const char* path = argc > 1 ? argv[1] : "target/accuracy/corners.csv";
    std::ifstream f(path);
    if (!f) {
        std::fprintf(stderr, "cannot open %s\n", path);
        return 1;
    }
    std::string line;
    std::getline(f, line);
    auto h = parse_header(line);
    std::getline(f, line);  // column names
    std::vector<Case> cases;
    while (std::getline(f, line)) {
        std::vector<double> v;
        std::istringstream in(line);
        std::string field;
        while (std::getline(in, field, ',')) v.push_back(std::stod(field));
        if (v.size() != 21) continue;
        Case c;
        for (int k = 0; k < 4; ++k) c.corners.emplace_back(v[13 + 2 * k], v[14 + 2 * k]);
        cases.push_back(c);
    }
    const double l = h["marker_mm"], half = l / 2.0;
    cv::Matx33d K(h["f_px"], 0, h["cx_px"], 0, h["f_px"], h["cy_px"], 0, 0, 1);
    // Marker frame of docs/conventions.md (qr order) and IPPE_SQUARE's own centred, y-up frame.
    std::vector<cv::Point3d> ours = {{-l, 0, 0}, {0, 0, 0}, {0, l, 0}, {-l, l, 0}};
    std::vector<cv::Point3d> square = {{-half, half, 0}, {half, half, 0}, {half, -half, 0}, {-half, -half, 0}};
    struct Method {
        const char* name;
        int flag;
        bool refine;
        const std::vector<cv::Point3d>* object;
    };
    std::vector<Method> methods = {
        {"opencv_ippe_square", cv::SOLVEPNP_IPPE_SQUARE, false, &square},
        {"opencv_ippe_square+refine_lm", cv::SOLVEPNP_IPPE_SQUARE, true, &square},
        {"opencv_ippe+refine_lm", cv::SOLVEPNP_IPPE, true, &ours},
    };
    const int rounds = 15;
    for (const auto& m : methods) {
        std::vector<double> per_call;
        volatile double sink = 0;
        for (int r = 0; r < rounds + 2; ++r) {
            auto start = std::chrono::steady_clock::now();
            for (const auto& c : cases) {
                cv::Mat rvec, tvec;
                cv::solvePnP(*m.object, c.corners, K, cv::noArray(), rvec, tvec, false, m.flag);
                if (m.refine) cv::solvePnPRefineLM(*m.object, c.corners, K, cv::noArray(), rvec, tvec);
                sink += tvec.at<double>(2);
            }
            double ns = std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - start).count();
            if (r >= 2) per_call.push_back(ns / cases.size());  // two warm-up rounds
        }
        std::sort(per_call.begin(), per_call.end());
        std::printf("%s %.0f %zu\n", m.name, per_call[per_call.size() / 2], cases.size());
    }
    return 0;
}
