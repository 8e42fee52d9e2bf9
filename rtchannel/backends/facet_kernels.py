"""Compiled (numba) kernels of the `facets` backend's surface maths: the same formulas as the numpy
reference in `surface_scattering` (Lambertian diffuse term, physical-optics triangle integral, Fresnel/slab
reflection, polarisation split, Kirchhoff roughness), fused per element so that ~10^6 facet paths per second
of motion cost ~0.3 us each. Tests compare them with the reference (tests/test_rcs_facets.py).

Every kernel takes the link's polarisation `pol` (0: "V", theta-hat; 1: "H", phi-hat) and the surface's rms
height `rough` [m] (0: the material's fixed scattering coefficient s_coef, as Sionna's; > 0: S and the
specular factor from the Kirchhoff model at each element's own angles, `surface_scattering.kirchhoff_specular`)."""
from __future__ import annotations

from collections.abc import Callable

import numba
import numpy as np

from processing.numba_math import sincos
from processing.radar.propagation import FOUR_PI_1_5  # the radar equation's home (a numba global)


def lambertian_po_gains(c, n, area, corners, p_a, p_b, eta, thickness, wavelength, s_coef, xpd, po, pol=0, rough=0.0):
    """(diffuse [E] real, PO [E] complex or None) path gains of elements (centroids c, unit normals n
    [E, 3], areas [E], corners [E, 3, 3] used with po) on p_a -> c -> p_b ([E, 3]) for a Lambertian surface
    of permittivity eta (None: perfect conductor), slab thickness (0: half-space), scattering coefficient
    s_coef (or rms height rough [m] > 0), cross-polar fraction xpd and link polarisation pol (0 V, 1 H); see
    `surface_scattering.facet_gains`."""
    e = len(c)
    corners = np.zeros((e, 3, 3)) if corners is None else corners
    # the elements as frame 0 of an indexed mesh: element i is facet i, its corners vertices 3i..3i+2
    return indexed_gains(np.asarray(c, float)[None], np.asarray(n, float)[None], np.asarray(area, float)[None],
                         np.asarray(corners, float).reshape(1, 3 * e, 3), np.arange(3 * e).reshape(e, 3),
                         np.zeros(e, np.int64), np.arange(e), p_a, p_b, eta, thickness, wavelength, s_coef, xpd, po,
                         pol=pol, rough=rough)


def indexed_gains(cent, norm, area, verts, faces, eb, ef, p_a, p_b, eta, thickness, wavelength, s_coef, xpd, po,
                  reverse=None, pol=0, rough=0.0):
    """`lambertian_po_gains` of elements given by index, without gathering them: element i is facet ef[i]
    of frame eb[i], with centroid cent[eb, ef], normal norm[eb, ef] ([B, F, 3]), area area[eb, ef] ([B, F])
    and corners verts[eb, faces[ef]] (verts [B, V, 3], faces [F, 3]); p_a, p_b [E, 3].

    reverse: optional bool [E]; where set, the same element on p_b -> c -> p_a (the merged monostatic
    twin) is evaluated in the same pass, sharing its geometry and triangle integral, and the result is
    (diffuse, PO, reverse diffuse [E], reverse PO [E] complex or None), valid where `reverse` is set."""
    e = len(eb)
    diffuse, specular = np.empty(e), np.empty(e if po else 0, complex)
    rev = np.zeros(0, np.bool_) if reverse is None else np.ascontiguousarray(reverse, np.bool_)
    rev_d, rev_p = np.zeros(e if rev.size else 0), np.zeros(e if rev.size and po else 0, complex)
    pec = eta is None
    arr = [np.ascontiguousarray(x, float) for x in (cent, norm, area, verts)]
    idx = [np.ascontiguousarray(x, np.int64) for x in (faces, eb, ef)]
    ends = [np.ascontiguousarray(x, float) for x in (p_a, p_b)]
    kernel: Callable[..., None] = _facets_parallel if e >= _PARALLEL_MIN else _facets_serial
    kernel(*arr, *idx, *ends, complex(0.0 if pec else eta), pec, float(thickness), float(wavelength), float(s_coef),
           float(xpd), po, diffuse, specular, rev, rev_d, rev_p, int(pol), float(rough))
    if reverse is not None:
        return diffuse, (specular if po else None), rev_d, (rev_p if po else None)
    return diffuse, (specular if po else None)


def wall_factors(cos_w, k_in, normal, eta, thickness, wavelength, pol=0, rough=0.0) -> np.ndarray:
    """conj(co-polar reflection coefficient) [N] (`surface_scattering.co_polar_reflection`) of a planar slab
    (normal [3], permittivity eta or None for a perfect conductor, thickness 0 for a half-space) at incidence
    cosines cos_w [N] for incident directions k_in [N, 3] and link polarisation pol (0 V, 1 H), times the
    Kirchhoff specular factor of rms height rough [m]; see `surface_scattering.wall_factor`."""
    out = np.empty(len(cos_w), complex)
    pec = eta is None
    kernel = _walls_parallel if len(out) >= _PARALLEL_MIN else _walls_serial
    kernel(np.ascontiguousarray(cos_w, float), np.ascontiguousarray(k_in, float), np.asarray(normal, float),
           complex(0.0 if pec else eta), pec, float(thickness), float(wavelength), out, int(pol), float(rough))
    return out


@numba.njit(cache=True, inline="always")
def _te_fraction_one(kx, ky, kz, nx, ny, nz, pol):
    """`te_fraction` of one direction k and normal n: theta_hat ~ (k x z) x k against e_perp = k x n; the
    horizontal polarisation (pol 1, phi-hat, the other transverse axis) carries the rest."""
    tx, ty, tz = -kx * kz, -ky * kz, kx * kx + ky * ky
    px, py, pz = ky * nz - kz * ny, kz * nx - kx * nz, kx * ny - ky * nx
    tn = tx * tx + ty * ty + tz * tz
    pn = px * px + py * py + pz * pz
    if tn > 1e-18 and pn > 1e-18:
        c2 = min((tx * px + ty * py + tz * pz) ** 2 / (tn * pn), 1.0)
        return 1.0 - c2 if pol == 1 else c2
    return 0.5  # normal incidence or vertical propagation: split equally


@numba.njit(cache=True, inline="always")
def _theta_hat_one(kx, ky, kz):
    """`surface_scattering.theta_hat` of one unit direction."""
    tx, ty, tz = -kx * kz, -ky * kz, kx * kx + ky * ky
    tn = np.sqrt(tx * tx + ty * ty + tz * tz)
    if tn > 1e-9:
        return tx / tn, ty / tn, tz / tn
    return 1.0, 0.0, 0.0


@numba.njit(cache=True, inline="always")
def _pol_hat_one(kx, ky, kz, pol):
    """`surface_scattering.polarization_hat` of one unit direction: theta-hat (pol 0) or phi-hat = z x k
    normalised (pol 1; y for vertical propagation)."""
    if pol == 0:
        return _theta_hat_one(kx, ky, kz)
    h = np.sqrt(kx * kx + ky * ky)
    if h > 1e-9:
        return -ky / h, kx / h, 0.0
    return 0.0, 1.0, 0.0


@numba.njit(cache=True, inline="always")
def _kirchhoff_one(q, rough, wavelength):
    """Kirchhoff specular factor exp(-(k rough q)^2 / 2) of rms height rough [m] for the phase-difference
    cosine sum q = n . (u_in + u_out) (2 cos(theta) at specular incidence)."""
    x = 2 * np.pi / wavelength * rough * q
    return np.exp(-0.5 * x * x)


@numba.njit(cache=True, inline="always")
def _co_polar_one(kx, ky, kz, nx, ny, nz, r_te, r_tm, pol):
    """`surface_scattering.co_polar_reflection` of one unit incident direction k and unit normal n."""
    kn = kx * nx + ky * ny + kz * nz
    rx, ry, rz = kx - 2 * kn * nx, ky - 2 * kn * ny, kz - 2 * kn * nz
    ix, iy, iz = _pol_hat_one(kx, ky, kz, pol)
    ox, oy, oz = _pol_hat_one(rx, ry, rz, pol)
    px, py, pz = ky * nz - kz * ny, kz * nx - kx * nz, kx * ny - ky * nx
    pn = np.sqrt(px * px + py * py + pz * pz)
    if pn <= 1e-9:  # normal incidence: any e_perp across the ray
        px, py, pz = iy * kz - iz * ky, iz * kx - ix * kz, ix * ky - iy * kx
        pn = np.sqrt(px * px + py * py + pz * pz)
    px, py, pz = px / pn, py / pn, pz / pn
    ax, ay, az = py * kz - pz * ky, pz * kx - px * kz, px * ky - py * kx  # e_par of the incident ray
    bx, by, bz = py * rz - pz * ry, pz * rx - px * rz, px * ry - py * rx  # e_par of the reflected ray
    return (r_te * (ix * px + iy * py + iz * pz) * (px * ox + py * oy + pz * oz)
            + r_tm * (ix * ax + iy * ay + iz * az) * (bx * ox + by * oy + bz * oz))


@numba.njit(cache=True, inline="always")
def _wall_one(e, cos_w, k_in, normal, eta, pec, thickness, wavelength, out, pol, rough):
    kn = np.sqrt(k_in[e, 0] ** 2 + k_in[e, 1] ** 2 + k_in[e, 2] ** 2)
    c = min(max(cos_w[e], 0.0), 1.0)
    if pec:
        r_te, r_tm = -1.0 + 0j, 1.0 + 0j
    else:
        r_te, r_tm = _slab_one(c, eta, thickness, wavelength)
    g = np.conj(_co_polar_one(k_in[e, 0] / kn, k_in[e, 1] / kn, k_in[e, 2] / kn,
                              normal[0], normal[1], normal[2], r_te, r_tm, pol))
    out[e] = g * _kirchhoff_one(2.0 * c, rough, wavelength) if rough > 0 else g


@numba.njit(cache=True, nogil=True)
def _walls_serial(cos_w, k_in, normal, eta, pec, thickness, wavelength, out, pol, rough):
    for e in range(cos_w.shape[0]):
        _wall_one(e, cos_w, k_in, normal, eta, pec, thickness, wavelength, out, pol, rough)


@numba.njit(parallel=True, cache=True, nogil=True)
def _walls_parallel(cos_w, k_in, normal, eta, pec, thickness, wavelength, out, pol, rough):
    for e in numba.prange(cos_w.shape[0]):
        _wall_one(e, cos_w, k_in, normal, eta, pec, thickness, wavelength, out, pol, rough)


@numba.njit(cache=True, inline="always")
def _slab_one(cos_i, eta, thickness, wavelength):
    """`slab_reflection` (r_te, r_tm) at one incidence cosine (thickness 0: half-space)."""
    b = np.sqrt(eta - (1.0 - cos_i * cos_i))
    r_te = (cos_i - b) / (cos_i + b)
    r_tm = (eta * cos_i - b) / (eta * cos_i + b)
    k_d = 2 * np.pi * thickness / wavelength
    if thickness > 0 and 2 * k_d * b.imag > -40.0:  # else the slab's back face is invisible (e^-40)
        e2 = np.exp(-2j * k_d * b)
        r_te = r_te * (1 - e2) / (1 - r_te * r_te * e2)
        r_tm = r_tm * (1 - e2) / (1 - r_tm * r_tm * e2)
    return r_te, r_tm


@numba.njit(cache=True, inline="always")
def _sinc(x):
    return 1.0 if x == 0.0 else sincos(x)[0] / x


@numba.njit(cache=True, inline="always")
def _dd2_cis(t0, t1, t2):
    """`_dd2_exp` at z = j (t0, t1, t2) for real t with t0 + t1 + t2 = 0 (phases about the centroid).

    With z = j t the first divided difference is exp[j p, j q] = exp(j (p + q) / 2) sinc((q - p) / 2), so
    the second one costs two complex exponentials and two sines (same branches as `_dd2_exp`)."""
    d01, d02, d12 = abs(t0 - t1), abs(t0 - t2), abs(t1 - t2)
    if max(d01, max(d02, d12)) < 1e-2:
        x0, x1, x2 = 1j * t0, 1j * t1, 1j * t2
        e1, e2, e3 = x0 + x1 + x2, x0 * x1 + x0 * x2 + x1 * x2, x0 * x1 * x2
        h2 = e1 * e1 - e2
        h3 = e1 * h2 - e2 * e1 + e3
        h4 = e1 * h3 - e2 * h2 + e3 * e1
        return 0.5 + e1 / 6 + h2 / 24 + h3 / 120 + h4 / 720
    if d01 >= d02 and d01 >= d12:
        a, b, c = t0, t1, t2
    elif d02 >= d12:
        a, b, c = t0, t2, t1
    else:
        a, b, c = t1, t2, t0
    # (exp[c, b] - exp[a, c]) / (j (b - a)); (c + b) / 2 = -a / 2 and (a + c) / 2 = -b / 2.
    # f_cb = exp(-j a / 2) sinc((b - c) / 2), f_ac = exp(-j b / 2) sinc((c - a) / 2), in real arithmetic with one
    # sincos per angle instead of six libm calls (the kernel ~11 % faster)
    sa, ca = sincos(0.5 * a)
    sb, cb = sincos(0.5 * b)
    s_cb, s_ac = _sinc(0.5 * (b - c)), _sinc(0.5 * (c - a))
    re, im = ca * s_cb - cb * s_ac, sb * s_ac - sa * s_cb  # f_cb - f_ac
    inv = 1.0 / (b - a)
    return complex(im * inv, -re * inv)  # (f_cb - f_ac) / (j (b - a))


@numba.njit(cache=True, inline="always")
def _diffuse_one(kx, ky, kz, ux, uy, uz, nx, ny, nz, area, scale, eta, pec, thickness, wavelength, s_coef, xpd, pol,
                 rough):
    """(Lambertian diffuse amplitude, r_te, r_tm at the incidence angle) of one facet: incident direction k,
    scattered direction u, unit normal n, area [m^2], radar-equation factor `scale`."""
    cos_i = min(max(-(nx * kx + ny * ky + nz * kz), 0.0), 1.0)
    cos_s = min(max(nx * ux + ny * uy + nz * uz, 0.0), 1.0)
    if rough > 0:  # S^2 = 1 - (specular factor)^2 at the incidence angle
        sp = _kirchhoff_one(2.0 * cos_i, rough, wavelength)
        s_coef = np.sqrt(max(1.0 - sp * sp, 0.0))
    gamma = 1.0
    r_te, r_tm = -1.0 + 0j, 1.0 + 0j
    if not pec:
        c2 = _te_fraction_one(kx, ky, kz, nx, ny, nz, pol)
        r_te, r_tm = _slab_one(cos_i, eta, thickness, wavelength)
        gamma = np.sqrt(c2 * abs(r_te) ** 2 + (1 - c2) * abs(r_tm) ** 2)
    return scale * s_coef * gamma * np.sqrt(4.0 * (1.0 - xpd) * cos_s * cos_i * max(area, 0.0)), r_te, r_tm


@numba.njit(cache=True, inline="always")
def _facet_one(e, cent, norm, area, verts, faces, eb, ef, p_a, p_b, eta, pec, thickness, wavelength, s_coef, xpd, po,
               out_d, out_p, pol, rough):
    """Fused Lambertian `diffuse_sqrt_rcs` and (with po) `po_sqrt_rcs` x sqrt(1 - S^2), times the
    radar-equation amplitude, of element e (facet ef[e] of frame eb[e]) on p_a -> c -> p_b (same maths as
    `facet_gains`' numpy path)."""
    b, f = eb[e], ef[e]
    c, n = cent[b, f], norm[b, f]
    ra2 = 0.0
    rb2 = 0.0
    for i in range(3):
        ra2 += (c[i] - p_a[e, i]) ** 2
        rb2 += (c[i] - p_b[e, i]) ** 2
    ra, rb = np.sqrt(ra2), np.sqrt(rb2)
    kx, ky, kz = (c[0] - p_a[e, 0]) / ra, (c[1] - p_a[e, 1]) / ra, (c[2] - p_a[e, 2]) / ra
    ux, uy, uz = (p_b[e, 0] - c[0]) / rb, (p_b[e, 1] - c[1]) / rb, (p_b[e, 2] - c[2]) / rb
    nx, ny, nz = n[0], n[1], n[2]
    scale = wavelength / (FOUR_PI_1_5 * ra * rb)
    out_d[e], r_te, r_tm = _diffuse_one(kx, ky, kz, ux, uy, uz, nx, ny, nz, area[b, f], scale, eta, pec, thickness,
                                        wavelength, s_coef, xpd, pol, rough)
    if not po:
        return ra, rb, kx, ky, kz, ux, uy, uz, 0.0, 1.0, r_te, r_tm, 0j
    hx, hy, hz = ux - kx, uy - ky, uz - kz  # u_tx + u_rx (facet -> antennas)
    nh = nx * hx + ny * hy + nz * hz
    h_len = max(np.sqrt(hx * hx + hy * hy + hz * hz), 1e-12)
    if not pec and (p_a[e, 0] != p_b[e, 0] or p_a[e, 1] != p_b[e, 1] or p_a[e, 2] != p_b[e, 2]):
        cos_b = min(max(nh / h_len, 0.0), 1.0)
        r_te, r_tm = _slab_one(cos_b, eta, thickness, wavelength)
    # else monostatic: the bisector is the incidence direction, r_te and r_tm are those at cos_i
    # the facet mirrors tx onto rx about the bisector (sign: a conducting plate at broadside gives +1)
    rho = -_co_polar_one(kx, ky, kz, hx / h_len, hy / h_len, hz / h_len, r_te, r_tm, pol)
    # Triangle integral of exp(j w . (r - centroid)), w = -k (u_tx + u_rx): phases t_i at the corners.
    k = 2 * np.pi / wavelength
    v0, v1, v2 = verts[b, faces[f, 0]], verts[b, faces[f, 1]], verts[b, faces[f, 2]]
    mx, my, mz = (v0[0] + v1[0] + v2[0]) / 3, (v0[1] + v1[1] + v2[1]) / 3, (v0[2] + v1[2] + v2[2]) / 3
    t0 = -k * (hx * (v0[0] - mx) + hy * (v0[1] - my) + hz * (v0[2] - mz))
    t1 = -k * (hx * (v1[0] - mx) + hy * (v1[1] - my) + hz * (v1[2] - mz))
    t2 = -k * (hx * (v2[0] - mx) + hy * (v2[1] - my) + hz * (v2[2] - mz))
    ax, ay, az = v1[0] - v0[0], v1[1] - v0[1], v1[2] - v0[2]
    bx, by, bz = v2[0] - v0[0], v2[1] - v0[1], v2[2] - v0[2]
    tri = 0.5 * np.sqrt((ay * bz - az * by) ** 2 + (az * bx - ax * bz) ** 2 + (ax * by - ay * bx) ** 2)
    integral = 2 * tri * _dd2_cis(t0, t1, t2)
    out_p[e] = (_specular_one(nh, s_coef, rough, wavelength) * scale * 1j * np.conj(rho)
                * (np.sqrt(4 * np.pi) / wavelength) * max(0.5 * nh, 0.0) * integral)
    return ra, rb, kx, ky, kz, ux, uy, uz, nh, h_len, r_te, r_tm, integral


@numba.njit(cache=True, inline="always")
def _specular_one(nh, s_coef, rough, wavelength):
    """Specular (PO) amplitude factor: sqrt(1 - S^2) of a fixed S, or the Kirchhoff factor of rms height rough
    at the facet's own phase-difference cosine sum nh = n . (u_tx + u_rx)."""
    if rough > 0:
        return _kirchhoff_one(nh, rough, wavelength)
    return np.sqrt(1.0 - s_coef * s_coef)


@numba.njit(cache=True, inline="always")
def _reverse_one(e, r, norm, area, eb, ef, p_a, p_b, eta, pec, thickness, wavelength, s_coef, xpd, po, out_d, out_p,
                 pol, rough):
    """`_facet_one` of element e on p_b -> c -> p_a from the forward pass's intermediates r: the reverse
    directions are the forward ones negated (exactly, in floating point), the bisector, the bistatic Fresnel
    coefficients and the triangle integral are the same, so only the incidence-dependent factors (Gamma,
    polarisation, rho) are evaluated anew; every value equals the one `_facet_one` computes for the
    swapped ends (tests/test_facet_speed_kernels.py)."""
    ra_f, rb_f, kx_f, ky_f, kz_f, ux_f, uy_f, uz_f, nh, h_len, r_te_b, r_tm_b, integral = r
    b, f = eb[e], ef[e]
    n = norm[b, f]
    ra, rb = rb_f, ra_f
    kx, ky, kz = -ux_f, -uy_f, -uz_f
    ux, uy, uz = -kx_f, -ky_f, -kz_f
    nx, ny, nz = n[0], n[1], n[2]
    scale = wavelength / (FOUR_PI_1_5 * ra * rb)
    out_d[e], r_te, r_tm = _diffuse_one(kx, ky, kz, ux, uy, uz, nx, ny, nz, area[b, f], scale, eta, pec, thickness,
                                        wavelength, s_coef, xpd, pol, rough)
    if not po:
        return
    hx, hy, hz = ux - kx, uy - ky, uz - kz
    if not pec and (p_a[e, 0] != p_b[e, 0] or p_a[e, 1] != p_b[e, 1] or p_a[e, 2] != p_b[e, 2]):
        r_te, r_tm = r_te_b, r_tm_b
    rho = -_co_polar_one(kx, ky, kz, hx / h_len, hy / h_len, hz / h_len, r_te, r_tm, pol)
    out_p[e] = (_specular_one(nh, s_coef, rough, wavelength) * scale * 1j * np.conj(rho)
                * (np.sqrt(4 * np.pi) / wavelength) * max(0.5 * nh, 0.0) * integral)


@numba.njit(cache=True, inline="always")
def _pair_one(e, cent, norm, area, verts, faces, eb, ef, p_a, p_b, eta, pec, thickness, wavelength, s_coef, xpd, po,
              out_d, out_p, rev, rev_d, rev_p, pol, rough):
    r = _facet_one(e, cent, norm, area, verts, faces, eb, ef, p_a, p_b, eta, pec, thickness, wavelength, s_coef, xpd,
                   po, out_d, out_p, pol, rough)
    if rev.shape[0] and rev[e]:
        _reverse_one(e, r, norm, area, eb, ef, p_a, p_b, eta, pec, thickness, wavelength, s_coef, xpd, po, rev_d, rev_p,
                     pol, rough)


@numba.njit(parallel=True, cache=True, nogil=True)
def _facets_parallel(cent, norm, area, verts, faces, eb, ef, p_a, p_b, eta, pec, thickness, wavelength, s_coef, xpd,
                     po, out_d, out_p, rev, rev_d, rev_p, pol, rough):
    for e in numba.prange(eb.shape[0]):
        _pair_one(e, cent, norm, area, verts, faces, eb, ef, p_a, p_b, eta, pec, thickness, wavelength, s_coef, xpd,
                  po, out_d, out_p, rev, rev_d, rev_p, pol, rough)


@numba.njit(cache=True, nogil=True)
def _facets_serial(cent, norm, area, verts, faces, eb, ef, p_a, p_b, eta, pec, thickness, wavelength, s_coef, xpd,
                   po, out_d, out_p, rev, rev_d, rev_p, pol, rough):
    for e in range(eb.shape[0]):
        _pair_one(e, cent, norm, area, verts, faces, eb, ef, p_a, p_b, eta, pec, thickness, wavelength, s_coef, xpd,
                  po, out_d, out_p, rev, rev_d, rev_p, pol, rough)


# Below this many elements a parallel launch costs more than it saves (~0.1-0.3 us per element against a
# thread wake-up of tens of us when idle). A bench-walk batch holds ~3e4-1e5 elements: parallel, the gains
# stage took 0.23 s against 0.33 s serial (benchmarks/bench_facets.py --quick, idle 2 cores). Dataset workers
# run one numba thread each (`rtchannel.dataset.runner.configure_worker`), so they never oversubscribe.
_PARALLEL_MIN = 20_000


def antenna_amplitudes(spec, position, targets) -> np.ndarray:
    """`processing.radar.antenna.gain` (amplitude sqrt(G) [N] of the antenna `spec` at `position` [3] (m) towards
    `targets` [N, 3] (m)) in one compiled pass for Gaussian and Yagi patterns, without the numpy
    temporaries; the same formulas, equal to it within float64 rounding (tests/test_facet_speed.py).
    Other kinds go to the numpy reference."""
    from processing.radar import antenna

    targets = np.ascontiguousarray(targets, float)
    if spec.kind not in ("gaussian", "yagi"):
        return antenna.gain(spec, position, targets)
    gauss = spec.kind == "gaussian"
    if gauss:
        pa, pe = np.radians(spec.hpbw_az_deg) ** -2, np.radians(spec.hpbw_el_deg) ** -2
        back = 0.0
    else:
        pa, pe = antenna._cos_exponent(spec.hpbw_az_deg), antenna._cos_exponent(spec.hpbw_el_deg)
        back = 10.0 ** (-spec.front_to_back_db / 10.0)
    out = np.empty(len(targets))
    kernel = _pattern_parallel if len(out) >= _PARALLEL_MIN else _pattern_serial
    kernel(targets, np.asarray(position, float), np.ascontiguousarray(spec.frame(position), float), gauss,
           float(pa), float(pe), float(back), 10.0 ** (-spec.floor_db / 10.0),
           10.0 ** (antenna.peak_gain_dbi(spec) / 10.0), antenna._TINY, out)
    return out


@numba.njit(cache=True, inline="always")
def _pattern_one(e, targets, pos, frame, gauss, pa, pe, back, floor, g0, tiny, out):
    """sqrt(g0 max(pattern, floor)) per target: `processing.radar.antenna._normalised` of the local direction
    (d @ frame) / |d| (boresight for a target at the antenna); pa, pe are the Gaussian's HPBW^-2 [rad^-2]
    or the Yagi's cos exponents, back the Yagi's back-lobe level."""
    dx, dy, dz = targets[e, 0] - pos[0], targets[e, 1] - pos[1], targets[e, 2] - pos[2]
    r = np.sqrt(dx * dx + dy * dy + dz * dz)
    if r > 0:
        x = (dx * frame[0, 0] + dy * frame[1, 0] + dz * frame[2, 0]) / r
        y = (dx * frame[0, 1] + dy * frame[1, 1] + dz * frame[2, 1]) / r
        z = (dx * frame[0, 2] + dy * frame[1, 2] + dz * frame[2, 2]) / r
    else:
        x, y, z = 1.0, 0.0, 0.0
    s2 = y * y + z * z
    axis = s2 < tiny
    den = max(s2, tiny)
    if gauss:
        psi = np.arctan2(np.sqrt(s2), x)
        q = pa if axis else (y * y * pa + z * z * pe) / den
        g = np.exp(-4.0 * np.log(2.0) * psi * psi * q)
    else:
        n = pa if axis else (y * y * pa + z * z * pe) / den
        g = max(max(x, 0.0) ** n, back * max(-x, 0.0))
    out[e] = np.sqrt(g0 * max(g, floor))


@numba.njit(cache=True, nogil=True)
def _pattern_serial(targets, pos, frame, gauss, pa, pe, back, floor, g0, tiny, out):
    for e in range(targets.shape[0]):
        _pattern_one(e, targets, pos, frame, gauss, pa, pe, back, floor, g0, tiny, out)


@numba.njit(parallel=True, cache=True, nogil=True)
def _pattern_parallel(targets, pos, frame, gauss, pa, pe, back, floor, g0, tiny, out):
    for e in numba.prange(targets.shape[0]):
        _pattern_one(e, targets, pos, frame, gauss, pa, pe, back, floor, g0, tiny, out)

