"""The inner loop of the virtual KR C4: servo cycles and physics sub-steps (scalar code).

Written as plain scalar Python on arrays so that it runs unchanged as pure Python or compiled by
numba (``@njit(cache=True)``) when numba is installed; :func:`get_kernel` picks.  State and
parameters travel in flat float arrays whose layout is given by the index constants below.
"""
from __future__ import annotations

import math

# state vector
S_Q, S_V, S_I, S_T, S_VX, S_VXD, S_BDIR, S_BS, S_BSIGN, S_TAU, S_QREF, S_Z, S_ZD = range(13)
N_STATE = 13

# parameter vector
(P_IZZ, P_MX, P_MY, P_FC, P_FS, P_VS, P_DELTA, P_FV, P_SUMW, P_VBL,
 P_KP, P_KV, P_KI, P_CIZZ, P_CMX, P_TMAX,
 P_TAMB, P_RTH, P_CTH, P_RCU,
 P_VIBG, P_VIBW, P_VIBZ,
 P_OFF, P_RA, P_RN, P_RPHI, P_KAPPA, P_TREF, P_LOADC, P_BA, P_BTAU, P_BVON,
 P_LUGRE, P_S0, P_S1, P_FPA, P_FPN, P_FPPHI) = range(39)
N_PARAM = 39


def servo_block(n_ticks, dt, nsub, qref, vff, aff, wn, text, st, F, E, p, k, w, c,
                samp_tick, out_q, out_tau, out_qcmd, out_temp, out_text, out_v):
    """Run ``n_ticks`` servo cycles of ``dt`` s, each with ``nsub`` physics sub-steps.

    ``qref``, ``vff``, ``aff`` hold n_ticks + 1 values: the reference at the start of every tick
    and at the end of the last.  Records the raw (true) signals at the ticks listed in ``samp_tick`` (ascending) into the
    ``out_*`` arrays; returns the number of samples recorded.  ``st`` and ``F`` (element torques)
    are updated in place.  Element j (stiffness ``k[j]``, damping ``c[j]``, saturation share
    ``w[j]``) has spring stretch ``E[j]`` and torque ``F[j] = k e + c de/dt``, clamped to its
    saturation; while clamped (slipping) the stretch relaxes, ``k e + c de/dt = F`` (implicit).

    With ``p[P_LUGRE]`` = 1 the elements are not used: friction is LuGre (Canudas de Wit et al.
    1995), one bristle state ``z`` (``st[S_Z]``, rad) with ``dz/dt = v - sigma0 |v| z / g(v)``,
    ``F = sigma0 z + sigma1 dz/dt + Fv v``, ``g`` the Stribeck magnitude (stiction ``Fs`` at rest);
    ``z`` is updated implicitly (unconditionally stable).  ``P_FPA``/``P_FPN``/``P_FPPHI`` make
    the friction magnitude depend on position: ``g`` and the saturations times
    ``1 + a sin(n q + phi)`` (either law).
    """
    Izz = p[P_IZZ]
    Mx = p[P_MX]
    My = p[P_MY]
    Fc = p[P_FC]
    dF = p[P_FS] - p[P_FC]
    vs = p[P_VS]
    delta = p[P_DELTA]
    Fv = p[P_FV]
    sumW = p[P_SUMW]
    vhalf = 0.5 * p[P_VBL]
    Kp = p[P_KP]
    Kv = p[P_KV]
    Ki = p[P_KI]
    cIzz = p[P_CIZZ]
    cMx = p[P_CMX]
    tmax = p[P_TMAX]
    Tamb = p[P_TAMB]
    Rth = p[P_RTH]
    Cth = p[P_CTH]
    rcu = p[P_RCU]
    vibG = p[P_VIBG]
    vibW = p[P_VIBW]
    vibZ = p[P_VIBZ]
    off = p[P_OFF]
    rA = p[P_RA]
    rN = p[P_RN]
    rPhi = p[P_RPHI]
    kappa = p[P_KAPPA]
    Tref = p[P_TREF]
    loadc = p[P_LOADC]
    bA = p[P_BA]
    btau = p[P_BTAU]
    bvon = p[P_BVON]
    lugre = p[P_LUGRE] != 0.0
    s0 = p[P_S0]
    s1 = p[P_S1]
    fpa = p[P_FPA]
    fpn = p[P_FPN]
    fpphi = p[P_FPPHI]

    q = st[S_Q]
    v = st[S_V]
    I = st[S_I]
    T = st[S_T]
    vx = st[S_VX]
    vxd = st[S_VXD]
    bdir = st[S_BDIR]
    bs = st[S_BS]
    bsign = st[S_BSIGN]
    tau_m = st[S_TAU]
    q_r = st[S_QREF]
    z = st[S_Z]
    zd = st[S_ZD]

    ne = len(k)
    h = dt / nsub
    gKv = cIzz * Kv
    gKi = cIzz * Kv * Ki * dt
    sqdt = 1.0 / math.sqrt(dt)
    vw2 = vibW * vibW
    vzw = 2.0 * vibZ * vibW
    rec = 0
    nrec = len(samp_tick)
    next_rec = samp_tick[0] if nrec > 0 else -1
    for i in range(n_ticks):
        # --- ambient vibration: band-limited deflection of the reference
        vxd += dt * (vibG * wn[i] * sqdt - vzw * vxd - vw2 * vx)
        vx += dt * vxd
        q_r = qref[i] + vx
        # --- cascaded position / velocity servo with feedforward and torque limit
        ev = vff[i] + Kp * (q_r - q) - v
        I += gKi * ev
        if I > tmax:
            I = tmax
        elif I < -tmax:
            I = -tmax
        tau_m = cIzz * aff[i] + cMx * math.cos(qref[i]) + gKv * ev + I
        if tau_m > tmax:
            tau_m = tmax
        elif tau_m < -tmax:
            tau_m = -tmax
        te = text[i]
        # --- backlash: direction reversals start an impact transient
        if bA != 0.0:
            if v > bvon:
                if bdir != 1.0:
                    bdir = 1.0
                    bs = 0.0
                    bsign = 1.0
            elif v < -bvon:
                if bdir != -1.0:
                    bdir = -1.0
                    bs = 0.0
                    bsign = -1.0
            x = bs / btau
            tb = bA * bsign * x * math.exp(1.0 - x) if x < 40.0 else 0.0
            bs += dt
        else:
            tb = 0.0
        scaleT = 1.0 + kappa * (T - Tref)
        pfric = 0.0
        for _ in range(nsub):
            cq = math.cos(q)
            # friction state -> torque
            Fel = 0.0
            if lugre:
                Fel = s0 * z + s1 * zd
            else:
                for j in range(ne):
                    Fel += F[j]
            Ff = Fel + Fv * scaleT * v
            tau_ext = te
            eff = off + tb
            if rA != 0.0:
                eff += rA * math.sin(rN * q + rPhi)
            qdd = (tau_m + tau_ext - Mx * cq - My * math.sin(q) - Ff - eff) / Izz
            v += h * qdd
            dq = h * v
            q += dq
            pfric += Ff * v
            # saturation of the elements at the new speed and position
            s = v if v >= 0.0 else -v
            if lugre:
                S = Fc + dF * math.exp(-math.pow(s / vs, delta))
            else:
                xb = (s - vhalf) / vhalf
                if xb <= 0.0:
                    S = sumW
                else:
                    if xb > 1.0:
                        xb = 1.0
                    b = xb * xb * (3.0 - 2.0 * xb)
                    g = Fc + dF * math.exp(-math.pow(s / vs, delta))
                    S = (1.0 - b) * sumW + b * g
            if loadc != 0.0:
                mc = Mx * math.cos(q)
                S += loadc * (mc if mc >= 0.0 else -mc)
            S *= scaleT
            if fpa != 0.0:
                S *= 1.0 + fpa * math.sin(fpn * q + fpphi)
            if lugre:  # implicit bristle update: z' = (z + h v) / (1 + h sigma0 |v| / g)
                z_new = (z + dq) / (1.0 + h * s0 * s / S)
                zd = (z_new - z) / h
                z = z_new
                continue
            for j in range(ne):
                ej = E[j] + dq
                Fj = k[j] * ej + c[j] * v
                sj = w[j] * S
                if Fj > sj or Fj < -sj:
                    Fj = sj if Fj > 0.0 else -sj
                    ch = c[j] / h
                    ej = (Fj + ch * E[j]) / (k[j] + ch)
                E[j] = ej
                F[j] = Fj
        # --- motor temperature: friction + copper losses
        P = (pfric if pfric >= 0.0 else -pfric) / nsub + rcu * tau_m * tau_m
        T += dt * (P - (T - Tamb) / Rth) / Cth
        if i == next_rec:
            out_q[rec] = q
            out_tau[rec] = tau_m
            out_qcmd[rec] = qref[i + 1]
            out_temp[rec] = T
            out_text[rec] = te
            out_v[rec] = v
            rec += 1
            next_rec = samp_tick[rec] if rec < nrec else -1

    st[S_Q] = q
    st[S_V] = v
    st[S_I] = I
    st[S_T] = T
    st[S_VX] = vx
    st[S_VXD] = vxd
    st[S_BDIR] = bdir
    st[S_BS] = bs
    st[S_BSIGN] = bsign
    st[S_TAU] = tau_m
    st[S_QREF] = q_r
    st[S_Z] = z
    st[S_ZD] = zd
    return rec


_compiled = None


def get_kernel():
    """The kernel, compiled with numba (cached on disk) if numba is available, else pure Python.

    Set the environment variable ``KUKAID_NO_NUMBA=1`` to force the pure-Python kernel.
    """
    global _compiled
    if _compiled is None:
        import os

        try:
            if os.environ.get("KUKAID_NO_NUMBA"):
                raise ImportError("disabled by KUKAID_NO_NUMBA")
            from numba import njit
        except ImportError:  # pure Python: same numbers, about 25 times slower
            _compiled = servo_block
        else:
            _compiled = njit(cache=True, nogil=True)(servo_block)
    return _compiled
