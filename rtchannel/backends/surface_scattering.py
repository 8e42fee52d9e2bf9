"""Surface scattering maths of the `facets` backend: Fresnel/slab reflection, Sionna RT's diffuse model,
physical optics (PO) over flat triangles, and the radar-equation amplitude. numpy reference maths, SI
units; the Lambertian diffuse + PO gains and the wall factors run through their compiled equivalents in
`facet_kernels`.

Common scale (Sionna RT's path-coefficient convention, isotropic unit-gain antennas): a path with
radar cross-section sigma at distances r_tx, r_rx has |a|^2 = P_r / P_t, i.e.

    |a| = lambda sqrt(sigma) / ((4 pi)^1.5 r_tx r_rx)            (`processing.radar.propagation.path_amplitude`)

Diffuse model (Sionna RT EM primer, "Scattering", after Degli-Esposti 2007/2011): the field scattered by
a surface element dA towards k_s is |E_s| = S Gamma sqrt(f_s(k_i, k_s) cos(theta_i) dA) |E_i| / r_s,
with S the scattering coefficient, Gamma^2 the reflected power fraction for the incident polarisation
and f_s a pattern normalised to 1 over the hemisphere. With a spherical incident wave and an
isotropic receiver this is a radar cross-section per element

    sigma_d = 4 pi S^2 Gamma^2 f_s cos(theta_i) dA       (Lambertian: 4 S^2 Gamma^2 cos(theta_i) cos(theta_s) dA)

whose amplitude is real and positive (Sionna's diffuse Jones matrix has no phase besides propagation).
Summed in power over a body this gives the closed forms `lambertian_sphere_rcs` and `lambertian_plate_rcs`
(`processing.radar.propagation`).
The diffuse model defines a power, not a phase: a rough surface's diffuse field has a random phase per
resolution cell, so `facet_gains` multiplies each element's diffuse amplitude by a fixed random phase
factor (`diffuse_phases`); the expected coherent power of a sum of elements is then its power sum, the
quantity the model defines, on any mesh of the surface.

Physical optics (Knott's scalar form, bistatic with the bisector direction): the facet's complex
sqrt(RCS) is

    s_po = j rho (sqrt(4 pi) / lambda) cos_b  I,   I = integral over the facet of exp(j k dL) dA

where dL is the path-length excess of a point of the facet over its centroid (linear in the point for a
far antenna), cos_b = n . (u_tx + u_rx) / 2 (u: unit vectors facet -> antenna), and rho the effective
reflection coefficient at the bisector angle (1 for a perfect conductor). I is integrated exactly for a
flat triangle (the divided difference of exp over its three corner phases, see `triangle_phase_integral`),
so facets larger than a wavelength are fine as long as the surface is flat to well under lambda/8 across
one facet. A flat plate then gives 4 pi A^2 / lambda^2 at broadside and a finely meshed sphere pi a^2.

Phase convention: the shared synthesiser forms exp(+j 2 pi f tau) (the beat of tx times conj(rx)), so
the gains returned here are the complex conjugates of Sionna's channel coefficients (exp(-j 2 pi f tau)).
Polarisation: a co-polarised link, both antennas vertical (theta-hat, Sionna's "V", the default) or both
horizontal (phi-hat, "H"; `processing.radar.antenna`); the diffuse model splits the incident power into
TE/TM fractions c^2, 1 - c^2 at each surface, |Gamma| = sqrt(c^2 |r_te|^2 + (1-c^2) |r_tm|^2) (Sionna's Gamma,
c^2 the TE share of the link's polarisation); wall, floor and PO reflections use the complex co-polar
coefficient projected on each ray's polarisation basis (`co_polar_reflection`, exact in every geometry:
+r_tm for a vertically polarised ray over the floor, r_te for a horizontally polarised one; on a side wall
seen by horizontal rays the roles swap). The Lambertian diffuse power depends on the polarisation only
through Gamma.

Roughness (`rtchannel.scene.material`): a material with an rms height takes S and the specular factor from
the Kirchhoff model at each element's angles (the clutter's patches, the walls' image reflections); the body
keeps Sionna's fixed S.
"""
from __future__ import annotations

from math import comb

import numpy as np

from processing.radar.propagation import FOUR_PI_1_5, path_amplitude  # noqa: F401 - the radar equation's home
from rtchannel.backends import facet_kernels
from processing.errors import InputError
# the one material model lives with the scene (walls, skin); its old home keeps the name importable
from rtchannel.scene.material import SurfaceMaterial  # noqa: F401


def pol_index(polarization: str) -> int:
    """The compiled kernels' code of a link polarisation: 0 for "V", 1 for "H"."""
    if polarization not in ("V", "H"):
        raise InputError(f"polarization must be 'V' or 'H', got {polarization!r}")
    return 0 if polarization == "V" else 1


def fresnel(cos_i, eta: complex | None):
    """Half-space Fresnel coefficients (r_te, r_tm) for incidence cosine `cos_i` (Sionna's sign
    convention: r_te = (c - b)/(c + b), r_tm = (eta c - b)/(eta c + b), b = sqrt(eta - sin^2)).
    eta None is a perfect conductor (-1, +1)."""
    c = np.clip(np.asarray(cos_i, dtype=float), 0.0, 1.0)
    if eta is None:
        return -np.ones(c.shape, complex), np.ones(c.shape, complex)
    b = np.sqrt(eta - (1.0 - c * c) + 0j)
    return (c - b) / (c + b), (eta * c - b) / (eta * c + b)


def slab_reflection(cos_i, eta: complex | None, thickness: float | None, wavelength: float):
    """(r_te, r_tm) of a single-layer slab (ITU-R P.2040, eqs. 43a/44; half-space if thickness is None)."""
    r_te, r_tm = fresnel(cos_i, eta)
    if eta is None or thickness is None or not np.isfinite(thickness):
        return r_te, r_tm
    c = np.clip(np.asarray(cos_i, dtype=float), 0.0, 1.0)
    q = 2 * np.pi * thickness / wavelength * np.sqrt(eta - (1.0 - c * c) + 0j)
    e2 = np.exp(-2j * q)
    return r_te * (1 - e2) / (1 - r_te ** 2 * e2), r_tm * (1 - e2) / (1 - r_tm ** 2 * e2)


def te_fraction(k_in: np.ndarray, normal: np.ndarray, polarization: str = "V") -> np.ndarray:
    """Fraction c^2 of a vertically (theta-hat) or horizontally (phi-hat) polarised incident wave's power in
    the TE component (H carries 1 - c^2 of V's: theta-hat and phi-hat span the transverse plane).

    k_in: propagation directions [..., 3] (unit); normal: surface normals [..., 3] (unit)."""
    z = np.array([0.0, 0.0, 1.0])
    theta_hat = np.cross(np.cross(k_in, z), k_in)  # z projected onto the transverse plane (up to sign)
    e_perp = np.cross(k_in, normal)
    tn = np.linalg.norm(theta_hat, axis=-1)
    pn = np.linalg.norm(e_perp, axis=-1)
    ok = (tn > 1e-9) & (pn > 1e-9)
    c = np.einsum("...i,...i->...", theta_hat, e_perp) / np.where(ok, tn * pn, 1.0)
    c2 = np.clip(c * c, 0.0, 1.0)
    c2 = 1.0 - c2 if pol_index(polarization) else c2
    # Normal incidence (no plane of incidence) or vertical propagation: split equally.
    return np.where(ok, c2, 0.5)


def gamma_magnitude(r_te, r_tm, c2):
    """Sionna's Gamma = sqrt(c^2 |r_te|^2 + (1 - c^2) |r_tm|^2) (reflected field fraction)."""
    return np.sqrt(c2 * np.abs(r_te) ** 2 + (1 - c2) * np.abs(r_tm) ** 2)


def theta_hat(k: np.ndarray) -> np.ndarray:
    """Unit vertical-polarisation vectors [..., 3] of waves travelling along unit `k` [..., 3]: z projected
    on the transverse plane, (k x z) x k normalised (x for vertical propagation, where it is undefined)."""
    t = np.stack([-k[..., 0] * k[..., 2], -k[..., 1] * k[..., 2], k[..., 0] ** 2 + k[..., 1] ** 2], axis=-1)
    n = np.linalg.norm(t, axis=-1, keepdims=True)
    return np.where(n > 1e-9, t / np.where(n > 1e-9, n, 1.0), np.array([1.0, 0.0, 0.0]))


def phi_hat(k: np.ndarray) -> np.ndarray:
    """Unit horizontal-polarisation vectors [..., 3] of waves travelling along unit `k` [..., 3]: z x k
    normalised (y for vertical propagation, where it is undefined)."""
    t = np.stack([-k[..., 1], k[..., 0], np.zeros(k.shape[:-1])], axis=-1)
    n = np.linalg.norm(t, axis=-1, keepdims=True)
    return np.where(n > 1e-9, t / np.where(n > 1e-9, n, 1.0), np.array([0.0, 1.0, 0.0]))


def polarization_hat(k: np.ndarray, polarization: str = "V") -> np.ndarray:
    """Unit field vectors [..., 3] of a "V" (`theta_hat`) or "H" (`phi_hat`) polarised wave along unit k."""
    return phi_hat(k) if pol_index(polarization) else theta_hat(k)


def co_polar_reflection(k_in, normal, r_te, r_tm, polarization: str = "V"):
    """Co-polar reflection coefficient of a vertically ("V") or horizontally ("H") polarised wave, exact in
    every geometry (Sionna RT's bases): with e_perp = k_i x n / |k_i x n|, e_par = e_perp x k for the
    incident and the reflected ray (k_r = k_i - 2 (k_i . n) n) and p-hat the polarisation vector of each ray
    (`polarization_hat`: theta-hat or phi-hat),

        Gamma = r_te (p_i . e_perp)(e_perp . p_r) + r_tm (p_i . e_par_i)(e_par_r . p_r).

    A vertical dipole over a conductor (r_te = -1, r_tm = +1) gives +1 at every angle (its image is in
    phase), a side wall seen by horizontal rays r_te; horizontally polarised, the floor gives r_te and the
    side wall r_tm. k_in [..., 3] unit incident directions, normal [..., 3] unit normals; r_te, r_tm [...] the
    Fresnel/slab coefficients. At normal incidence e_perp is any vector across the ray (the result does not
    depend on it)."""
    k = np.asarray(k_in, float)
    n = np.broadcast_to(np.asarray(normal, float), k.shape)
    k_r = k - 2 * np.einsum("...i,...i->...", k, n)[..., None] * n
    th_i, th_r = polarization_hat(k, polarization), polarization_hat(k_r, polarization)
    e_perp = np.cross(k, n)
    nrm = np.linalg.norm(e_perp, axis=-1, keepdims=True)
    fallback = np.cross(th_i, k)  # normal incidence: any e_perp across the ray
    e_perp = np.where(nrm > 1e-9, e_perp / np.where(nrm > 1e-9, nrm, 1.0),
                      fallback / np.linalg.norm(fallback, axis=-1, keepdims=True))
    e_par_i, e_par_r = np.cross(e_perp, k), np.cross(e_perp, k_r)
    dot = lambda a, b: np.einsum("...i,...i->...", a, b)  # noqa: E731
    return r_te * dot(th_i, e_perp) * dot(e_perp, th_r) + r_tm * dot(th_i, e_par_i) * dot(e_par_r, th_r)


def _f_alpha(alpha: int, cos_i: np.ndarray) -> np.ndarray:
    """Normalisation F_alpha(theta_i) of the directive lobe (Degli-Esposti 2007; Sionna primer)."""
    sin2 = 1.0 - cos_i * cos_i
    total = np.zeros_like(cos_i)
    odd_sum = np.zeros_like(cos_i)
    for k in range(alpha + 1):
        if k % 2 == 0:
            i_k = 2 * np.pi / (k + 1) * np.ones_like(cos_i)
        else:
            w = (k - 1) // 2
            odd_sum = odd_sum + comb(2 * w, w) * sin2 ** w / 4.0 ** w
            i_k = 2 * np.pi / (k + 1) * cos_i * odd_sum
        total = total + comb(alpha, k) * i_k
    return total / 2.0 ** alpha


def scattering_pattern(mat: SurfaceMaterial, k_i: np.ndarray, k_s: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Scattering pattern f_s(k_i, k_s, n) [1/sr], normalised to 1 over the hemisphere.

    k_i: incident propagation direction (towards the surface), k_s: scattered direction (away from it),
    normal: outward unit normal; all [..., 3] unit vectors."""
    cos_s = np.clip(np.einsum("...i,...i->...", normal, k_s), 0.0, 1.0)
    if mat.pattern == "lambertian":
        return cos_s / np.pi
    cos_i = np.clip(-np.einsum("...i,...i->...", normal, k_i), 0.0, 1.0)
    k_r = k_i + 2 * cos_i[..., None] * normal
    lobe_r = (0.5 * (1 + np.einsum("...i,...i->...", k_r, k_s))) ** mat.alpha_r
    if mat.pattern == "directive":
        return lobe_r / _f_alpha(mat.alpha_r, cos_i)
    if mat.pattern == "backscattering":
        lobe_i = (0.5 * (1 - np.einsum("...i,...i->...", k_i, k_s))) ** mat.alpha_i
        lam = mat.lambda_
        return (lam * lobe_r + (1 - lam) * lobe_i) / (lam * _f_alpha(mat.alpha_r, cos_i)
                                                      + (1 - lam) * _f_alpha(mat.alpha_i, cos_i))
    raise InputError(f"unknown scattering pattern {mat.pattern!r}")


def _dd2_exp(z: np.ndarray) -> np.ndarray:
    """Second divided difference of exp at the three points z [..., 3] (complex), evaluated stably."""
    m = z.mean(axis=-1)
    x = z - m[..., None]
    x0, x1, x2 = x[..., 0], x[..., 1], x[..., 2]
    spread = np.max(np.abs(x[..., :, None] - x[..., None, :]), axis=(-1, -2))
    # Taylor: exp[x0,x1,x2] = sum_n h_n(x) / (n+2)!, h_n complete homogeneous symmetric polynomials.
    e1, e2, e3 = x0 + x1 + x2, x0 * x1 + x0 * x2 + x1 * x2, x0 * x1 * x2
    h1 = e1
    h2 = e1 * h1 - e2
    h3 = e1 * h2 - e2 * h1 + e3
    h4 = e1 * h3 - e2 * h2 + e3 * h1
    taylor = 0.5 + h1 / 6 + h2 / 24 + h3 / 120 + h4 / 720
    # Otherwise: f[a,c,b] = (f[c,b] - f[a,c]) / (b - a) with (a, b) the farthest pair (|b - a| = spread).
    pairs = np.array([[0, 1, 2], [0, 2, 1], [1, 2, 0]])  # (a, b, c)
    d = np.stack([np.abs(x0 - x1), np.abs(x0 - x2), np.abs(x1 - x2)], axis=-1)
    sel = pairs[np.argmax(d, axis=-1)]
    a = np.take_along_axis(x, sel[..., :1], -1)[..., 0]
    b = np.take_along_axis(x, sel[..., 1:2], -1)[..., 0]
    c = np.take_along_axis(x, sel[..., 2:], -1)[..., 0]

    def dd1(p, q):
        h = q - p
        small = np.abs(h) < 1e-6
        phi = np.where(small, 1 + h / 2, np.expm1(h) / np.where(small, 1.0, h))
        return np.exp(p) * phi

    big = spread >= 1e-2
    denom = np.where(big, b - a, 1.0)
    general = (dd1(c, b) - dd1(a, c)) / denom
    return np.exp(m) * np.where(big, general, taylor)


def triangle_phase_integral(corners: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Exact integral over flat triangles of exp(j w . (r - centroid)) dA [m^2].

    corners: [..., 3, 3] triangle corners (m); w: [..., 3] phase gradient (rad/m). For w = 0 this is the
    area. Uses the Hermite-Genocchi identity: integral = 2 A exp[z0, z1, z2], z_i = j w . (p_i - c)."""
    c = corners.mean(axis=-2)
    area = 0.5 * np.linalg.norm(np.cross(corners[..., 1, :] - corners[..., 0, :],
                                         corners[..., 2, :] - corners[..., 0, :]), axis=-1)
    z = 1j * np.einsum("...ki,...i->...k", corners - c[..., None, :], w)
    return 2 * area * _dd2_exp(z)


def diffuse_sqrt_rcs(mat: SurfaceMaterial, k_i, k_s, normal, area, gamma,
                     wavelength: float | None = None) -> np.ndarray:
    """Real sqrt(sigma_d) [m] of surface elements under Sionna's diffuse model:
    sigma_d = 4 pi S^2 Gamma^2 (1 - K_x) f_s cos(theta_i) dA, S at the incidence for a rough material
    (`SurfaceMaterial.scattering_at`; `wavelength` [m] needed then)."""
    cos_i = np.clip(-np.einsum("...i,...i->...", normal, k_i), 0.0, 1.0)
    f_s = scattering_pattern(mat, k_i, k_s, normal)
    if mat.roughness_m is None:
        s = mat.scattering_coefficient
    elif wavelength is None:
        raise ValueError("diffuse_sqrt_rcs: a rough material needs the wavelength")
    else:
        s = mat.scattering_at(cos_i, wavelength)
    return s * gamma * np.sqrt(4 * np.pi * (1 - mat.xpd_coefficient) * f_s * cos_i * np.maximum(area, 0.0))


def po_sqrt_rcs(corners, u_tx, u_rx, normal, rho, wavelength: float) -> np.ndarray:
    """Complex PO sqrt(sigma) [m] of flat triangles (see the module doc), in the synthesiser's phase
    convention. u_tx, u_rx: unit vectors facet -> antennas [..., 3]; rho: co-polar reflection factor in
    Sionna's (channel) convention, conjugated here (1 for a perfect conductor)."""
    k = 2 * np.pi / wavelength
    cos_b = np.clip(0.5 * np.einsum("...i,...i->...", normal, u_tx + u_rx), 0.0, None)
    # Path-length excess of r over the centroid is -(r - c).(u_tx + u_rx) for far antennas.
    integral = triangle_phase_integral(corners, -k * (u_tx + u_rx))
    return 1j * np.conj(rho) * (np.sqrt(4 * np.pi) / wavelength) * cos_b * integral


def wall_factor(wall, cos_w, k_in, wavelength, polarization: str = "V"):
    """Conjugated co-polar slab reflection coefficient of `wall` at incidence cosines cos_w [N] for
    incident directions k_in [N, 3] (synthesiser phase convention) of a "V" or "H" polarised link:
    conj(`co_polar_reflection`) with `slab_reflection`, times the Kirchhoff specular factor
    exp(-(4 pi sigma_h cos_w / lambda)^2 / 2) of the wall's rms height ``roughness_m`` (0 or absent: smooth),
    the same roughness the clutter's diffuse and specular parts use (`rtchannel.scene.material`). Compiled."""
    eta = None if wall.relative_permittivity is None else complex(wall.relative_permittivity)
    return facet_kernels.wall_factors(cos_w, k_in, np.asarray(wall.normal, float), eta,
                                      getattr(wall, "thickness", None) or 0.0, wavelength, pol_index(polarization),
                                      float(getattr(wall, "roughness_m", 0.0) or 0.0))


def diffuse_phases(seed: int | None, n_facets: int) -> np.ndarray | None:
    """Fixed random phase factors exp(j phi_f) [n_facets] of the diffuse field of each facet (None: no
    random phase, every diffuse gain real and positive).

    A rough surface's diffuse field is the sum of many small contributions within a resolution cell, so
    its phase is random and uniform per cell; it is fixed for the cell (the roughness moves with the
    skin), so a facet keeps its phase in every frame and on every path (direct, via a wall, double
    bounce), and Doppler stays coherent. With independent uniform phases the expected coherent power of a
    facet sum equals its incoherent (power) sum, which is area-weighted and therefore independent of the
    mesh resolution. The stream is seeded by (seed, n_facets): meshes of different resolution get
    independent phases, the same mesh always the same ones."""
    if seed is None:
        return None
    return np.exp(1j * np.random.default_rng([int(seed), int(n_facets)]).uniform(0.0, 2 * np.pi, int(n_facets)))


def facet_gains(mat: SurfaceMaterial, wavelength: float, c, n, area, corners, p_a, p_b, po: bool, phase=None,
                polarization: str = "V", compiled: bool = True):
    """Complex path gains (synthesiser convention) of facets on p_a -> facet -> p_b.

    c: centroids [N, 3] (m); n: unit normals [N, 3]; area: [N] (m^2); corners: [N, 3, 3] (m, used with po);
    p_a, p_b: points [3] or [N, 3] (m); phase: unit factors [N] multiplying the diffuse part (see
    `diffuse_phases`), or None; polarization: the link's, "V" or "H". Diffuse term (Sionna's model), plus
    sqrt(1 - S^2) x PO if `po` (the Kirchhoff specular factor for a rough material). The Lambertian pattern
    runs compiled unless `compiled` is False (the numpy reference the kernels are tested against)."""
    p_a, p_b = np.broadcast_to(p_a, c.shape), np.broadcast_to(p_b, c.shape)
    if mat.pattern == "lambertian" and compiled:
        diffuse, specular = _compiled_gains(mat, wavelength, c, n, area, corners, p_a, p_b, po, polarization)
    else:
        da, db = c - p_a, c - p_b
        ra, rb = np.linalg.norm(da, axis=1), np.linalg.norm(db, axis=1)
        k_i = da / ra[:, None]  # incident propagation direction
        u_b = -db / rb[:, None]  # facet -> receiver
        cos_i = np.clip(-np.einsum("ij,ij->i", n, k_i), 0.0, 1.0)
        c2 = te_fraction(k_i, n, polarization)
        r_te, r_tm = slab_reflection(cos_i, mat.eta, mat.thickness, wavelength)
        scale = wavelength / (FOUR_PI_1_5 * ra * rb)
        diffuse = scale * diffuse_sqrt_rcs(mat, k_i, u_b, n, area, gamma_magnitude(r_te, r_tm, c2), wavelength)
        if po:
            half = -k_i + u_b
            h_len = np.maximum(np.linalg.norm(half, axis=1), 1e-12)
            cos_b = np.einsum("ij,ij->i", n, half) / h_len
            rb_te, rb_tm = slab_reflection(cos_b, mat.eta, mat.thickness, wavelength)
            # the facet mirrors tx onto rx about the bisector: the co-polar coefficient of that reflection,
            # sign-normalised so that a conducting plate at broadside gives rho = +1 (Knott's PO form)
            rho = -co_polar_reflection(k_i, half / h_len[:, None], rb_te, rb_tm, polarization)
            specular = (scale * mat.specular_at(np.einsum("ij,ij->i", n, half), wavelength)
                        * po_sqrt_rcs(corners, -k_i, u_b, n, rho, wavelength))
    g = diffuse * phase if phase is not None else diffuse.astype(complex)
    return g + specular if po else g


def facet_gains_indexed(mat: SurfaceMaterial, wavelength: float, cent, norm, area, verts, faces, eb, ef, p_a, p_b,
                        po: bool, phase=None, polarization: str = "V"):
    """`facet_gains` of facets ef [N] of frames eb [N] read in place: centroids cent and normals norm
    [B, F, 3], areas [B, F] (m^2), corners verts[eb, faces[ef]] (verts [B, V, 3] m, faces [F, 3]). The
    Lambertian model's compiled kernel reads them by index (no [N, 3, 3] gather); other patterns gather."""
    if mat.pattern != "lambertian":
        corners = verts[eb[:, None], faces[ef]] if po else None
        return facet_gains(mat, wavelength, cent[eb, ef], norm[eb, ef], area[eb, ef], corners, p_a, p_b, po, phase,
                           polarization)
    shape = (len(eb), 3)
    s_coef, rough = mat.kernel_surface()
    diffuse, specular = facet_kernels.indexed_gains(
        cent, norm, area, verts, faces, eb, ef, np.broadcast_to(p_a, shape), np.broadcast_to(p_b, shape), mat.eta,
        mat.thickness or 0.0, wavelength, s_coef, mat.xpd_coefficient, po, pol=pol_index(polarization), rough=rough)
    g = diffuse * phase if phase is not None else diffuse.astype(complex)
    return g + specular if po else g


def lambertian_gains(mat: SurfaceMaterial, wavelength: float, c, n, area, p_a, p_b,
                     polarization: str = "V") -> np.ndarray:
    """Real path gains [E] of surface elements (centroids c [E, 3], normals, areas [E]) on p_a -> c -> p_b
    (points [E, 3]) under the Lambertian diffuse model: the fused, compiled equivalent of
    `path_amplitude` applied to `diffuse_sqrt_rcs`."""
    return _compiled_gains(mat, wavelength, c, n, area, None, p_a, p_b, False, polarization)[0]


def _compiled_gains(mat, wavelength, c, n, area, corners, p_a, p_b, po, polarization="V"):
    """(diffuse [E] real, PO [E] complex or None) path gains of the Lambertian model (compiled kernels)."""
    s_coef, rough = mat.kernel_surface()
    return facet_kernels.lambertian_po_gains(c, n, area, corners, p_a, p_b, mat.eta, mat.thickness or 0.0, wavelength,
                                             s_coef, mat.xpd_coefficient, po, pol_index(polarization), rough)
