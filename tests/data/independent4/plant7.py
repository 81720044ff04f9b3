# Independent brake plant from SPEC.md (braketest7). Scalar RK4, dt = 1 ms, hard end stops by projection.
import math, json, os, sys
import numpy as np
k=1.4; R=287.0; T0=293.15; P0=1.0e5; PCR=0.528
C1=math.sqrt(k/R*(2/(k+1))**((k+1)/(k-1))); C2=math.sqrt(2*k/(R*(k-1)))
A=4*math.pi*0.05**2; L=0.060; M=20.0
BAR=1e5

def flow(pu,pd,area,cf,T=T0):
    if pu<=pd: return 0.0
    r=pd/pu
    if r<=PCR: return cf*area*C1*pu/math.sqrt(T)
    return cf*area*C2*pu/math.sqrt(T)*r**(1/k)*math.sqrt(max(0.0,1-r**((k-1)/k)))

def nominal():
    F0=4.0*BAR*A; Fc=150.0
    K=(7.2*BAR*A-F0-Fc)/L
    return dict(Ps=7.7,d_or=1.25e-3,Cf=0.8,V0=3.0e-3,F0=F0,K=K,s0=1e5,s1=2e3,B=2e3,Fc=150.0,Fs=300.0,vs=0.01,d_leak=0.0)

def loco(rng,spread=0.05):
    p=nominal()
    for key in ['V0','F0','K','Cf','Fc','Fs']:
        p[key]*=1+rng.uniform(-spread,spread)
    p['Ps']=7.7+rng.uniform(-0.03,0.03)
    return p

def simulate(p,eff=None,tend=60.0,dt=1e-3):
    """returns true gauge pressure at 100 Hz (6000 samples) and travel.
    eff: dict of hooks/options."""
    eff=eff or {}
    Ps=p['Ps']; area=math.pi/4*p['d_or']**2; cf=p['Cf']; V0=p['V0']; F0=p['F0']; K=p['K']
    s0=p['s0']; s1=p['s1']; B=p['B']; Fc=p['Fc']; Fs=p['Fs']; vs=p['vs']
    aleak=math.pi/4*p['d_leak']**2
    Mp=p.get('M',M)
    Ls=eff.get('stop_L',L)
    Tin=eff.get('gas_temperature',T0)
    thermal = ('heat_transfer' in eff) or ('gas_temperature' in eff) or eff.get('thermal',False)
    tau_h=eff.get('heat_transfer',None)
    delay=eff.get('transport_delay',0.0)
    vlag=eff.get('valve_lag',0.0)
    droop=eff.get('regulator_droop',0.0)
    prog=eff.get('progressive_spring',0.0)
    lam=eff.get('laminar_leak',0.0)/1000.0
    supply_fn=eff.get('supply_fn')      # t -> bar g
    area_fn=eff.get('area_fn')          # t,P -> multiplier of orifice area
    extra_leak_fn=eff.get('leak_fn')    # t,P(Pa abs) -> kg/s
    fric_fn=eff.get('fric_fn')          # t,x -> multiplier on Fc,Fs
    spring_fn=eff.get('spring_fn')      # x -> spring force beyond preload (replaces K x)
    second_vol=eff.get('second_vol')    # (V2 m3, d mm) second volume behind restriction
    mfull=cf*math.pi/4*(1.25e-3)**2*C1*(Ps*BAR+P0)/math.sqrt(T0)
    def deriv(t,s):
        P,x,v,z,m,P2=s
        V=V0+A*x
        T = P*V/(m*R) if thermal else T0
        ps=(supply_fn(t) if supply_fn else Ps)*BAR+P0
        if t<delay: ain=0.0
        else:
            ain=area*(1-math.exp(-(t-delay)/vlag)) if vlag>0 else area
        if area_fn: ain*=area_fn(t,P)
        if droop>0:
            if ps<=P: mi=-flow(P,ps,ain,cf,T)
            else:
                lo=0.0; hi=flow(ps,P,ain,cf,Tin)
                for _ in range(30):
                    mm=0.5*(lo+hi); pse=ps-droop*BAR*mm/mfull
                    h=(flow(pse,P,ain,cf,Tin) if pse>P else 0.0)-mm
                    if h>0: lo=mm
                    else: hi=mm
                mi=0.5*(lo+hi)
        else:
            mi=flow(ps,P,ain,cf,Tin) if ps>=P else -flow(P,ps,ain,cf,T)
        mo=flow(P,P0,aleak,cf,T) if aleak>0 else 0.0
        mo+=lam*max(P-P0,0.0)/(7*BAR)
        if extra_leak_fn: mo+=extra_leak_fn(t,P)
        m2=0.0
        if second_vol:
            V2,d2=second_vol; a2=math.pi/4*(d2*1e-3)**2
            m2 = flow(P,P2,a2,cf,T0) if P>=P2 else -flow(P2,P,a2,cf,T0)
        # piston
        g=Fc+(Fs-Fc)*math.exp(-(v/vs)**2)
        if fric_fn:
            mul=fric_fn(t,x); g*=mul
        dz=v-s0*abs(v)*z/g
        Ff=s0*z+s1*dz+B*v
        Fsp = spring_fn(x) if spring_fn else K*x*(1+prog*x/L)
        Fn=(P-P0)*A-F0-Fsp-Ff
        a=Fn/Mp; vx=v
        if x<=0.0 and v<=0.0 and a<0: a=0.0; vx=0.0; dz=0.0
        if x>=Ls and v>=0.0 and a>0: a=0.0; vx=0.0; dz=0.0
        dV=A*vx
        Tm_in=Tin if mi>0 else T
        dP=k*R/V*(Tm_in*mi-T*(mo+m2))-k*P/V*dV
        if thermal and tau_h:
            dP+=(P/T)*(T0-T)/tau_h
        dP2=0.0
        if second_vol: dP2=R*T0/second_vol[0]*m2  # isothermal second volume
        return (dP,vx,a,dz,mi-mo-m2,dP2)
    P=P0; x=0.0; v=0.0; z=0.0; m=P0*V0/(R*T0); P2=P0
    s=[P,x,v,z,m,P2]
    nsub=int(round(0.01/dt)); N=int(round(tend/0.01))
    out=np.zeros(N); xs=np.zeros(N)
    t=0.0
    for i in range(N):
        out[i]=(s[0]-P0)/BAR; xs[i]=s[1]
        for _ in range(nsub):
            k1=deriv(t,s)
            s2=[s[j]+0.5*dt*k1[j] for j in range(6)]
            k2=deriv(t+0.5*dt,s2)
            s3=[s[j]+0.5*dt*k2[j] for j in range(6)]
            k3=deriv(t+0.5*dt,s3)
            s4=[s[j]+dt*k3[j] for j in range(6)]
            k4=deriv(t+dt,s4)
            s=[s[j]+dt/6*(k1[j]+2*k2[j]+2*k3[j]+k4[j]) for j in range(6)]
            if s[1]<0: s[1]=0.0; s[2]=max(s[2],0.0)
            if s[1]>Ls: s[1]=Ls; s[2]=min(s[2],0.0)
            t=(i*nsub+_+1)*dt
    return out,xs

def adc(p_bar,rng,sigma=0.01,eff=None):
    eff=eff or {}
    p=p_bar.copy()
    if 'sensor_lag' in eff:
        tau=eff['sensor_lag']; y=np.zeros_like(p); a=math.exp(-0.01/tau); y[0]=p[0]
        # finer: integrate exactly-ish with 100 substeps
        yy=p[0]
        for i in range(1,len(p)):
            # linear interpolation of input across the sample
            for j in range(10):
                u=p[i-1]+(p[i]-p[i-1])*(j+1)/10
                yy+= (u-yy)*(1-math.exp(-0.001/tau))
            y[i]=yy
        p=y
    if 'sensor_gain' in eff: p=p*eff['sensor_gain']
    if 'sensor_offset' in eff: p=p+eff['sensor_offset']
    if 'meas_fn' in eff: p=eff['meas_fn'](p)
    pn=p+rng.normal(0,sigma,len(p))
    c=np.clip(np.round(4095*(0.1+0.08*pn)),0,4095).astype(int)
    if 'adc_fn' in eff: c=eff['adc_fn'](c)
    return c

def write_set(d,traces,meta=None,per_meta=None,loco='loco-77',label='normal'):
    os.makedirs(os.path.join(d,'traces'),exist_ok=True)
    rows=['file,label,locomotive,split']
    for i,c in enumerate(traces):
        fn='traces/rel_%02d.csv'%i
        with open(os.path.join(d,fn),'w') as f:
            f.write('# locomotive: %s\n# label: %s\n# source: braketest7 plant\n'%(loco,label))
            for kk,vv in (meta or {}).items(): f.write('# %s: %s\n'%(kk,vv))
            if per_meta:
                for kk,vv in per_meta[i].items(): f.write('# %s: %s\n'%(kk,vv))
            f.write('t_s,adc\n')
            for j,cc in enumerate(c): f.write('%.2f,%d\n'%(j*0.01,cc))
        rows.append('%s,%s,%s,train'%(fn,label,loco))
    open(os.path.join(d,'manifest.csv'),'w').write('\n'.join(rows)+'\n')
