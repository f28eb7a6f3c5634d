"""BSIM3v3 cards (level 8, version 3.3.0) shared by the BSIM3 packing tests and
``benchmarks/bsim3_scaling.py``: ngspice's ``examples/Monte_Carlo/MC_ring.sp`` NMOS and
PMOS cards, abridged to their binning-free core (capMod 3, mobMod 1)."""

CARDS = """.model n1 nmos level=8 version=3.3.0 tnom=27.0 nch=2.498e+17 tox=9e-09 xj=1e-07
+ lint=9.36e-8 wint=1.47e-7 vth0=.6322 k1=.756 k2=-3.83e-2 k3=-2.612 dvt0=2.812
+ dvt1=0.462 dvt2=-9.17e-2 nlx=3.52291e-08 w0=1.163e-6 k3b=2.233 vsat=86301.58
+ ua=6.47e-9 ub=4.23e-18 uc=-4.706281e-11 rdsw=650 u0=388.3203 wr=1 a0=.3496967
+ ags=.1 b0=0.546 b1=1 keta=-3.605872e-02 a1=2.778747e-02 a2=.9 voff=-6.735529e-02
+ nfactor=1.139926 cit=1.622527e-04 cdsc=-2.147181e-05 eta0=1.0281729e-02
+ etab=-5.042203e-03 dsub=.31871233 pclm=1.114846 pdiblc1=2.45357e-03
+ pdiblc2=6.406289e-03 drout=.31871233 pscbe1=5000000 pscbe2=5e-09 pdiblcb=-.234
.model p1 pmos level=8 version=3.3.0 tnom=27.0 nch=3.533024e+17 tox=9e-09 xj=1e-07
+ lint=6.23e-8 wint=1.22e-7 vth0=-.6732829 k1=.8362093 k2=-8.606622e-02 k3=1.82
+ dvt0=1.903801 dvt1=.5333922 dvt2=-.1862677 nlx=1.28e-8 w0=2.1e-6 k3b=-0.24
+ vsat=103503.2 ua=1.39995e-09 ub=1.e-19 uc=-2.73e-11 rdsw=460 u0=138.7609
+ a0=.4716551 ags=0.12 keta=-1.871516e-03 a1=.3417965 a2=0.83 voff=-.074182
+ nfactor=1.54389 cit=-1.015667e-03 cdsc=8.937517e-04 eta0=6.024776e-02
+ etab=-4.64593e-03 dsub=.23222404 pclm=.989 pdiblc1=2.07418e-02 pdiblc2=1.33813e-3"""
