#include "algorithms/internal/plane_fit.hpp"

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define RGBD_PLANE_FIT_X86 1
#endif

namespace rgbd::internal {
namespace {

/// Whether a point at height h with normal term t votes: |h| <= band and |t| >= cos_tilt
/// (without normals, t = 1 and cos_tilt = -1: every point within the band).
inline bool votes(double h, double t, double band, double cos_tilt) {
    return std::abs(h) <= band && std::abs(t) >= cos_tilt;
}

#if defined(RGBD_PLANE_FIT_X86)
/// 4 points at a time (AVX2) from j; returns the votes and advances j past them.
__attribute__((target("avx2"))) std::size_t votes_avx2(const PlaneVoteInput& in,
                                                       const Eigen::Vector3d& n, double d,
                                                       double band, double cos_tilt,
                                                       std::size_t& j) {
    const __m256d va = _mm256_set1_pd(n.x()), vb = _mm256_set1_pd(n.y()),
                  vc = _mm256_set1_pd(n.z()), vd = _mm256_set1_pd(d), vband = _mm256_set1_pd(band),
                  vcos = _mm256_set1_pd(cos_tilt), sign = _mm256_set1_pd(-0.0);
    __m256i lanes = _mm256_setzero_si256();  // minus the number of votes in each lane
    for (; j + 4 <= in.m; j += 4) {
        const __m256d h = _mm256_add_pd(
            _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(_mm256_loadu_pd(in.px + j), va),
                                        _mm256_mul_pd(_mm256_loadu_pd(in.py + j), vb)),
                          _mm256_mul_pd(_mm256_loadu_pd(in.pz + j), vc)),
            vd);
        __m256d ok = _mm256_cmp_pd(_mm256_andnot_pd(sign, h), vband, _CMP_LE_OQ);
        if (in.nx) {
            const __m256d t =
                _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(_mm256_loadu_pd(in.nx + j), va),
                                            _mm256_mul_pd(_mm256_loadu_pd(in.ny + j), vb)),
                              _mm256_mul_pd(_mm256_loadu_pd(in.nz + j), vc));
            ok = _mm256_and_pd(ok, _mm256_cmp_pd(_mm256_andnot_pd(sign, t), vcos, _CMP_GE_OQ));
        }
        lanes = _mm256_add_epi64(lanes, _mm256_castpd_si256(ok));
    }
    alignas(32) std::int64_t sums[4];
    _mm256_store_si256(reinterpret_cast<__m256i*>(sums), lanes);
    return static_cast<std::size_t>(-(sums[0] + sums[1] + sums[2] + sums[3]));
}

/// The same, 2 points at a time (SSE2, every x86-64 CPU).
std::size_t votes_sse2(const PlaneVoteInput& in, const Eigen::Vector3d& n, double d, double band,
                       double cos_tilt, std::size_t& j) {
    const __m128d va = _mm_set1_pd(n.x()), vb = _mm_set1_pd(n.y()), vc = _mm_set1_pd(n.z()),
                  vd = _mm_set1_pd(d), vband = _mm_set1_pd(band), vcos = _mm_set1_pd(cos_tilt),
                  sign = _mm_set1_pd(-0.0);
    __m128i lanes = _mm_setzero_si128();
    for (; j + 2 <= in.m; j += 2) {
        const __m128d h = _mm_add_pd(_mm_add_pd(_mm_add_pd(_mm_mul_pd(_mm_loadu_pd(in.px + j), va),
                                                           _mm_mul_pd(_mm_loadu_pd(in.py + j), vb)),
                                                _mm_mul_pd(_mm_loadu_pd(in.pz + j), vc)),
                                     vd);
        __m128d ok = _mm_cmple_pd(_mm_andnot_pd(sign, h), vband);
        if (in.nx) {
            const __m128d t = _mm_add_pd(_mm_add_pd(_mm_mul_pd(_mm_loadu_pd(in.nx + j), va),
                                                    _mm_mul_pd(_mm_loadu_pd(in.ny + j), vb)),
                                         _mm_mul_pd(_mm_loadu_pd(in.nz + j), vc));
            ok = _mm_and_pd(ok, _mm_cmpge_pd(_mm_andnot_pd(sign, t), vcos));
        }
        lanes = _mm_add_epi64(lanes, _mm_castpd_si128(ok));
    }
    alignas(16) std::int64_t sums[2];
    _mm_store_si128(reinterpret_cast<__m128i*>(sums), lanes);
    return static_cast<std::size_t>(-(sums[0] + sums[1]));
}
#endif

}  // namespace

std::size_t count_plane_votes(const PlaneVoteInput& in, const Eigen::Vector3d& n, double d,
                              double band, double cos_tilt) {
    std::size_t j = 0, count = 0;
#if defined(RGBD_PLANE_FIT_X86)
    static const bool avx2 = __builtin_cpu_supports("avx2");
    count =
        avx2 ? votes_avx2(in, n, d, band, cos_tilt, j) : votes_sse2(in, n, d, band, cos_tilt, j);
#endif
    for (; j < in.m; ++j) {
        const double h = n.x() * in.px[j] + n.y() * in.py[j] + n.z() * in.pz[j] + d;
        const double t = in.nx ? n.x() * in.nx[j] + n.y() * in.ny[j] + n.z() * in.nz[j] : 1.0;
        count += votes(h, t, band, in.nx ? cos_tilt : -1.0);
    }
    return count;
}

}  // namespace rgbd::internal
