// treelog.hpp: a tree log for your own ray tracer (C++17, this one header, no dependencies).
//
// For each pixel the feedback names, trace the ray through the pixel's centre and tell the log about every ray
// you trace: the eye ray, each shadow ray, each reflection and transmission ray, with its parent. Then write the
// log and upload it. The format: docs/scene-format.md, "Tree log"; at most 64 trees and 4 MB a log.
//
//     #include "treelog.hpp"
//
//     treelog::TreeLog log;
//     treelog::PixelTree& tree = log.pixel(12, 30);            // x from the left, y from the top
//     int eye = tree.eye(treelog::xyz(origin), treelog::xyz(dir));
//     tree.hit(eye, t, treelog::xyz(p), treelog::xyz(n), obj); // or tree.miss(eye); n: the shading normal
//     tree.shadow(eye, treelog::xyz(so), treelog::xyz(l), /*light*/ 0, /*occluded*/ false,
//                 treelog::xyz(contribution), treelog::xyz(w));
//     int r = tree.reflection(eye, treelog::xyz(ro), treelog::xyz(rd), treelog::xyz(w_r));
//     tree.radiance(eye, treelog::xyz(L));                     // what the ray carries back
//     tree.terms(eye, treelog::xyz(ambient), treelog::xyz(diffuse), treelog::xyz(specular));
//     tree.color(treelog::xyz(L));                             // optional: the pixel's final linear colour
//     log.write("treelog.json");
//
// Vectors are treelog::Vec ({x, y, z} doubles): treelog::xyz(v) reads v.x, v.y, v.z (glm, your own struct),
// treelog::vec(v) reads v[0], v[1], v[2] (arrays, Eigen). A number that is not finite (NaN, infinity) is
// written as null, so the file stays JSON and the service's check names the field.
#pragma once

#include <array>
#include <cmath>
#include <cstdio>
#include <deque>
#include <fstream>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace treelog {

using Vec = std::array<double, 3>;

template <class V>
Vec xyz(const V& v) { return {double(v.x), double(v.y), double(v.z)}; }

template <class V>
Vec vec(const V& v) { return {double(v[0]), double(v[1]), double(v[2])}; }

struct Hit {
    Vec point;   // where the ray hit
    Vec normal;  // the shading normal there, turned towards the ray
    int object;  // index in the scene's "objects"
};

struct Terms {
    Vec ambient, diffuse, specular;  // the local shading at the hit
};

struct Node {
    int id = 0;
    int parent = -1;                 // -1: the eye ray (written as null)
    std::string kind;                // eye | shadow | reflection | transmission
    Vec origin{}, direction{};
    std::optional<double> t;         // distance to the hit (shadow: to the occluder); none = a miss
    std::optional<Hit> hit;
    std::optional<int> light;        // shadow rays: the light's index
    std::optional<bool> occluded;    // shadow rays: blocked or not
    std::optional<Vec> radiance;     // what the ray carries back (linear)
    std::optional<Vec> weight;       // product of the K's from the eye down to this ray
    std::optional<Terms> terms;
};

namespace detail {

inline void number(std::ostream& out, double x) {
    if (!std::isfinite(x)) {
        out << "null";
        return;
    }
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.17g", x);
    out << buf;
}

inline void vector(std::ostream& out, const Vec& v) {
    out << '[';
    for (int i = 0; i < 3; ++i) {
        if (i) out << ", ";
        number(out, v[i]);
    }
    out << ']';
}

inline void optional_vector(std::ostream& out, const std::optional<Vec>& v) {
    if (v) vector(out, *v);
    else out << "null";
}

}  // namespace detail

// The rays traced for one pixel: a flat list of nodes, each with its parent's id.
class PixelTree {
public:
    PixelTree(int x, int y) : x_(x), y_(y) {}

    // A ray of `kind` from `origin` along `direction`, child of node `parent` (-1 for the eye ray): its id.
    int add(const std::string& kind, int parent, const Vec& origin, const Vec& direction,
            std::optional<Vec> weight = std::nullopt) {
        if (kind != "eye" && kind != "shadow" && kind != "reflection" && kind != "transmission")
            throw std::invalid_argument("kind must be eye, shadow, reflection or transmission, not " + kind);
        if ((parent < 0) != (kind == "eye"))
            throw std::invalid_argument("the eye ray has no parent; every other ray has one");
        if (parent >= int(nodes_.size())) throw std::invalid_argument("no node to be the parent");
        Node n;
        n.id = int(nodes_.size());
        n.parent = parent;
        n.kind = kind;
        n.origin = origin;
        n.direction = direction;
        n.weight = weight;
        nodes_.push_back(n);
        return n.id;
    }

    int eye(const Vec& origin, const Vec& direction) { return add("eye", -1, origin, direction, Vec{1, 1, 1}); }

    int reflection(int parent, const Vec& origin, const Vec& direction, const Vec& weight) {
        return add("reflection", parent, origin, direction, weight);
    }

    int transmission(int parent, const Vec& origin, const Vec& direction, const Vec& weight) {
        return add("transmission", parent, origin, direction, weight);
    }

    // A shadow ray from the parent's hit towards light `light`: `radiance` is the light's contribution
    // f_att I cos(theta) f (0 when occluded), `weight` the parent's. A blocked one may then get hit(...)
    // for its occluder.
    int shadow(int parent, const Vec& origin, const Vec& direction, int light, bool occluded, const Vec& radiance,
               const Vec& weight) {
        int id = add("shadow", parent, origin, direction, weight);
        nodes_[id].light = light;
        nodes_[id].occluded = occluded;
        nodes_[id].radiance = radiance;
        return id;
    }

    void hit(int id, double t, const Vec& point, const Vec& normal, int object) {
        node(id).t = t;
        node(id).hit = Hit{point, normal, object};
    }

    void miss(int id) {
        node(id).t.reset();
        node(id).hit.reset();
    }

    void radiance(int id, const Vec& l) { node(id).radiance = l; }
    void weight(int id, const Vec& w) { node(id).weight = w; }
    void terms(int id, const Vec& ambient, const Vec& diffuse, const Vec& specular) {
        node(id).terms = Terms{ambient, diffuse, specular};
    }
    void color(const Vec& c) { color_ = c; }

    Node& node(int id) { return nodes_.at(std::size_t(id)); }
    const std::vector<Node>& nodes() const { return nodes_; }

    void write_json(std::ostream& out) const {
        out << "{\"pixel\": [" << x_ << ", " << y_ << "]";
        if (color_) {
            out << ", \"color\": ";
            detail::vector(out, *color_);
        }
        out << ", \"nodes\": [";
        for (std::size_t i = 0; i < nodes_.size(); ++i) {
            const Node& n = nodes_[i];
            out << (i ? ",\n    " : "\n    ") << "{\"id\": " << n.id << ", \"parent\": ";
            if (n.parent < 0) out << "null";
            else out << n.parent;
            out << ", \"kind\": \"" << n.kind << "\", \"origin\": ";
            detail::vector(out, n.origin);
            out << ", \"direction\": ";
            detail::vector(out, n.direction);
            out << ", \"t\": ";
            if (n.t) detail::number(out, *n.t);
            else out << "null";
            out << ", \"hit\": ";
            if (n.hit) {
                out << "{\"point\": ";
                detail::vector(out, n.hit->point);
                out << ", \"normal\": ";
                detail::vector(out, n.hit->normal);
                out << ", \"object\": " << n.hit->object << "}";
            } else {
                out << "null";
            }
            out << ", \"light\": ";
            if (n.light) out << *n.light;
            else out << "null";
            out << ", \"occluded\": " << (n.occluded ? (*n.occluded ? "true" : "false") : "null");
            out << ", \"radiance\": ";
            detail::optional_vector(out, n.radiance);
            out << ", \"weight\": ";
            detail::optional_vector(out, n.weight);
            out << ", \"terms\": ";
            if (n.terms) {
                out << "{\"ambient\": ";
                detail::vector(out, n.terms->ambient);
                out << ", \"diffuse\": ";
                detail::vector(out, n.terms->diffuse);
                out << ", \"specular\": ";
                detail::vector(out, n.terms->specular);
                out << "}";
            } else {
                out << "null";
            }
            out << "}";
        }
        out << "]}";
    }

private:
    int x_, y_;
    std::optional<Vec> color_;
    std::vector<Node> nodes_;
};

// The trees of a few pixels; write() saves the JSON the service takes.
class TreeLog {
public:
    static constexpr std::size_t max_trees = 64;

    // A new tree for pixel (x, y), x from the left, y from the top. The reference stays valid.
    PixelTree& pixel(int x, int y) {
        if (trees_.size() >= max_trees) throw std::length_error("a tree log holds at most 64 trees");
        trees_.emplace_back(x, y);
        return trees_.back();
    }

    std::string json() const {
        std::ostringstream out;
        out << "{\"trees\": [";
        for (std::size_t i = 0; i < trees_.size(); ++i) {
            out << (i ? ",\n  " : "\n  ");
            trees_[i].write_json(out);
        }
        out << "]}\n";
        return out.str();
    }

    // Writes the log to `path`; false if the file could not be written.
    bool write(const std::string& path) const {
        std::ofstream file(path);
        file << json();
        return bool(file);
    }

private:
    std::deque<PixelTree> trees_;  // a deque: pixel() hands out references that stay valid
};

}  // namespace treelog
