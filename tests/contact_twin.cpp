// optix/contact.cuh compiled as host C++ by tests/contact_twin.rs: reads the case table that
// test writes (one case a line, f32 values as hex bits, sections split by '|') and prints one
// line per value whose bits differ from what src/dem/model/contact.rs computed (the first 20),
// then a summary.
// ±0 count as equal (the partner's negated zero springs). Compiled with -DMOCHI_LOAD_HISTORY for
// the Mindlin–Deresiewicz law, whose springs carry 4 more values (reversal, normal force), and
// with -DMOCHI_COHESIVE=true for the cohesion laws. Each case carries its material table and
// cohesion parameters; the law reads them as the device reads the uploaded ones.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

// CUDA's qualifiers and vector types, as the host sees them.
#define __forceinline__ inline
#define __device__
struct float3 {
    float x, y, z;
};
struct float4 {
    float x, y, z, w;
};
inline float3 make_float3(float x, float y, float z) { return {x, y, z}; }
inline float4 make_float4(float x, float y, float z, float w) { return {x, y, z, w}; }

// CUDA's bit casts, as the host does them.
inline unsigned int __float_as_uint(float x) {
    unsigned int u;
    std::memcpy(&u, &x, 4);
    return u;
}
inline float __uint_as_float(unsigned int u) {
    float x;
    std::memcpy(&x, &u, 4);
    return x;
}

#include "physics.cuh"
#include "contact.cuh"

#ifdef MOCHI_LOAD_HISTORY
// Values of a springs section: tangential, rolling, reversal, normal force.
static const size_t SPRINGS = 10;
#else
// Values of a springs section: tangential, rolling.
static const size_t SPRINGS = 6;
#endif

static float from_bits(const std::string& s) {
    uint32_t u = (uint32_t)std::stoul(s, nullptr, 16);
    float f;
    std::memcpy(&f, &u, 4);
    return f;
}

static std::vector<std::string> words(const std::string& section) {
    std::vector<std::string> out;
    std::stringstream s(section);
    std::string w;
    while (s >> w) out.push_back(w);
    return out;
}

static int differences = 0;
static int line_number = 0;

static void check(const char* what, float got, const std::string& want) {
    float w = from_bits(want);
    uint32_t a, b;
    std::memcpy(&a, &got, 4);
    std::memcpy(&b, &w, 4);
    if (a != b && !(got == 0.0f && w == 0.0f) && ++differences <= 20) {
        std::printf("case %d %s: got %08x (%g), contact.rs %s (%g)\n", line_number, what, a, got,
                    want.c_str(), w);
    }
}

static void check3(const char* what, float3 got, const std::vector<std::string>& want, size_t at) {
    check(what, got.x, want[at]);
    check(what, got.y, want[at + 1]);
    check(what, got.z, want[at + 2]);
}

static float3 vec(const std::vector<std::string>& w, size_t at) {
    return make_float3(from_bits(w[at]), from_bits(w[at + 1]), from_bits(w[at + 2]));
}

static MochiBody body(const std::vector<std::string>& w) {
    MochiBody b;
    b.c = vec(w, 0);
    b.v = vec(w, 3);
    b.w = vec(w, 6);
    b.r = from_bits(w[9]);
    b.m = from_bits(w[10]);
    b.material = std::stoul(w[11]);
    return b;
}

// The springs of a section from `at` on.
static MochiSprings springs(const std::vector<std::string>& w, size_t at) {
    MochiSprings k;
    k.tangential = vec(w, at);
    k.rolling = vec(w, at + 3);
#ifdef MOCHI_LOAD_HISTORY
    k.reversal = vec(w, at + 6);
    k.normal = from_bits(w[at + 9]);
#endif
    return k;
}

// A contact's force, torque and springs against a contact section ("1", then those).
static void check_contact(const char* what, float3 force, float3 torque, const MochiSprings& k,
                          const std::vector<std::string>& want) {
    std::string w(what);
    check3((w + " force").c_str(), force, want, 1);
    check3((w + " torque").c_str(), torque, want, 4);
    check3((w + " tangential spring").c_str(), k.tangential, want, 7);
    check3((w + " rolling spring").c_str(), k.rolling, want, 10);
#ifdef MOCHI_LOAD_HISTORY
    check3((w + " reversal").c_str(), k.reversal, want, 13);
    check((w + " normal force kept").c_str(), k.normal, want[16]);
#endif
}

int main() {
    std::string line;
    while (std::getline(std::cin, line)) {
        ++line_number;
        std::vector<std::vector<std::string>> s;
        std::stringstream ss(line);
        std::string section;
        while (std::getline(ss, section, '|')) s.push_back(words(section));
        // Parameters: law, rolling model, turns, keeps, dt, k, box, the material table's
        // columns and the box walls' column, the bridge's volume, tension and rupture gap, the
        // cohesion energy density, the reach and the bridge's viscosity, then each entry of the
        // table: its law's rate, E*, G*, ζ, μ, μ_r, Γ and its bridge's tension and rupture gap.
        const std::vector<std::string>& h = s[0];
        MochiLaw g{};
        g.dem.law = std::stoul(h[0]);
        g.dem.rolling_model = std::stoul(h[1]);
        g.dem.turns = std::stoul(h[2]);
        g.dem.slots = std::stoul(h[3]);  // the law reads only whether contacts keep springs
        g.dem.dt = from_bits(h[4]);
        g.dem.stiffness = from_bits(h[5]);
        for (int a = 0; a < 3; ++a) {
            g.dem.box_lo[a] = from_bits(h[6 + a]);
            g.dem.box_hi[a] = from_bits(h[9 + a]);
        }
        g.dem.columns = std::stoul(h[12]);
        g.dem.box_column = std::stoul(h[13]);
        g.cohesion.bridge_volume = from_bits(h[14]);
        g.cohesion.bridge_tension = from_bits(h[15]);
        g.cohesion.bridge_rupture = from_bits(h[16]);
        g.cohesion.density = from_bits(h[17]);
        g.dem.reach = from_bits(h[18]);
        g.cohesion.bridge_viscosity = from_bits(h[19]);
        std::vector<MochiTableLaw> laws((h.size() - 20) / 9);
        for (size_t k = 0; k < laws.size(); ++k) {
            MochiPairLaw& l = laws[k].law;
            const std::string* x = &h[20 + 9 * k];
            l.rate = from_bits(x[0]);
            l.e_star = from_bits(x[1]);
            l.g_star = from_bits(x[2]);
            l.damping_ratio = from_bits(x[3]);
            l.sliding = from_bits(x[4]);
            l.rolling = from_bits(x[5]);
            l.adhesion = from_bits(x[6]);
            laws[k].bridge.tension = from_bits(x[7]);
            laws[k].bridge.rupture = from_bits(x[8]);
        }
        g.laws = laws.data();
        MochiBody i = body(s[1]);
        MochiBody j = body(s[2]);
        MochiSprings old = springs(s[3], 0);
        // From i's side: touching, then force, torque, springs; from j's side the same.
        const std::vector<std::string>& from_i = s[4];
        const std::vector<std::string>& from_j = s[5];
        // Whether the pair was in contact at the last step (the last section).
        bool bonded = s[9][0] == "1";
        MochiPairContact c;
        bool touching = mochi_pair_contact(g, i, j, old, bonded, c);
        if (touching != (from_i[0] == "1") || touching != (from_j[0] == "1")) {
            std::printf("case %d: touching %d, contact.rs %s and %s\n", line_number, touching,
                        from_i[0].c_str(), from_j[0].c_str());
            ++differences;
        } else if (touching) {
            check_contact("pair's", c.force, c.torque, c.springs, from_i);
            float3 t = g.dem.turns ? mochi_partner_torque(j.r, c) : mochi_zero3();
            check_contact("partner's", mochi_neg(c.force), t, mochi_negated(c.springs), from_j);
        }
        // Walls: normal, tangential, torque, then (wall, springs) kept and their count. Each
        // touched its wall at the last step; the springs kept of wall w are (w, w, w)·1e-6 and
        // the rolling one their negative.
        const std::vector<std::string>& walls = s[6];
        std::vector<std::pair<unsigned int, MochiSprings>> kept;
        MochiWalls w = mochi_wall_contacts(
            g, i,
            [](unsigned int wall, MochiSprings& k) {
                float x = (float)wall * 1e-6f;
                k.tangential = make_float3(x, x, x);
                k.rolling = make_float3(-x, -x, -x);
#ifdef MOCHI_LOAD_HISTORY
                k.reversal = make_float3(x, -x, x);
                k.normal = x;
#endif
                return true;
            },
            [&](unsigned int wall, MochiSprings springs) { kept.push_back({wall, springs}); });
        check3("walls' normal force", w.normal, walls, 0);
        check3("walls' tangential force", w.tangential, walls, 3);
        check3("walls' torque", w.torque, walls, 6);
        // A surface: n, overlap, velocity, column, its own μ (negative: none), then the contact.
        const std::vector<std::string>& on = s[7];
        MochiSurface surface = mochi_surface_contact(g, i, vec(on, 0), from_bits(on[3]),
                                                     vec(on, 4), std::stoul(on[7]),
                                                     from_bits(on[8]), old);
        check_contact("surface's", surface.force, surface.torque, surface.springs, s[8]);
        size_t count = std::stoul(walls.back());
        if (count != kept.size()) {
            std::printf("case %d: %zu walls kept, contact.rs %zu\n", line_number, kept.size(),
                        count);
            ++differences;
            continue;
        }
        for (size_t k = 0; k < count; ++k) {
            size_t at = 9 + (1 + SPRINGS) * k;
            if (std::to_string(kept[k].first) != walls[at]) {
                std::printf("case %d: wall %u kept, contact.rs %s\n", line_number, kept[k].first,
                            walls[at].c_str());
                ++differences;
            }
            check3("wall's tangential spring", kept[k].second.tangential, walls, at + 1);
            check3("wall's rolling spring", kept[k].second.rolling, walls, at + 4);
#ifdef MOCHI_LOAD_HISTORY
            check3("wall's reversal", kept[k].second.reversal, walls, at + 7);
            check("wall's normal force kept", kept[k].second.normal, walls[at + 10]);
#endif
        }
    }
    std::printf("%d cases, %d differences\n", line_number, differences);
    return 0;
}
