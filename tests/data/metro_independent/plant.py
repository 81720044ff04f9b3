#!/usr/bin/env python3
"""Independent reservoir/compressor plant (own physics). Writes MetroPT-3-like CSV."""
import math, random, sys, argparse, datetime
R=287.0; cv=718.0; cp=cv+R; PA=1.01325e5; TAMB=293.15
def sim(a):
    rnd=random.Random(a.seed)
    V=a.V; dt=a.dt
    p=(9.3e5)+PA; T=TAMB+a.T0off
    m=p*V/(R*T); Tw=TAMB+a.T0off
    theta=55.0  # oil temp C
    loaded=False
    mgas_cv=m*cv
    hA=mgas_cv/a.tau_h if a.tau_h>0 else 0.0    # gas heat conductance (to ambient or to wall)
    Cw=mgas_cv/a.wall_ratio if a.wall_ratio>0 else 0.0   # wall capacity; ratio = gas/wall
    Gwa=Cw/a.wall_cool if a.wall_ratio>0 else 0.0
    t=0.0; rows=[]; nextrow=0.0; cyc=-1; unload_t=None; cycle_starts=[]
    # consumption: orifice choked, proportional to p_abs: mdot = k*p_abs ; k from a.cons (g/s at 10 bar g)
    k=a.cons*1e-3/(10e5+PA)
    leak_step_k=a.step_leak*1e-3/(10e5+PA)
    rowi=0; Ttot=a.duration
    events=[]
    while t<=Ttot+1e-9:
        pg=(p-PA)/1e5
        if t>=nextrow-1e-9:
            tj=int(round(nextrow + (rnd.randint(-a.jitter,a.jitter) if a.jitter else 0)))
            rows.append((tj,pg,theta,loaded))
            rowi+=1
            nextrow+=a.row_dt+ (rnd.choice([-1,0,0,0]) if a.rowvar else 0)
        # governor
        if not loaded and pg<a.p_lo:
            loaded=True
        elif loaded and pg>a.p_hi:
            loaded=False; cyc+=1; unload_t=t; cycle_starts.append(t)
        # delivery
        mdot_in=0.0
        if loaded:
            fl=a.flow*1e-3
            if a.heat_derate>0: fl*=max(0.2,1-a.heat_derate*(theta-55.0)/30.0)
            mdot_in=fl
        Tin=theta+273.15
        if a.oil_phys_const>0: Tin=a.oil_phys_const+273.15
        if a.tau_const and a.tau_h>0: hA=m*cv/a.tau_h
        # consumption
        mout=k*p
        if a.p2: mout=k*p*p/(10e5+PA)
        if a.thresh_cons>0 and pg>a.thresh: mout+=a.thresh_cons*1e-3
        if a.step_leak>0 and t>=Ttot*a.step_at: mout+=leak_step_k*p
        if a.laminar>0: mout+=a.laminar*1e-3*(p-PA)/(10e5)
        # events
        ev_in=0.0
        if unload_t is not None and (a.event_cycle==cyc or (a.event_cycle==-2 and cyc>=0)):
            s=t-unload_t
            if a.event_at<=s<a.event_at+a.event_dur:
                mout+=a.event_g*1e-3/a.event_dur
                events.append((cyc,round(t)))
            if a.event_back and a.event_at+a.event_dur+a.back_gap<=s<a.event_at+2*a.event_dur+a.back_gap:
                ev_in=a.event_g*1e-3/a.event_dur
        # heat
        if a.wall_ratio>0:
            Q=hA*(Tw-T)
            dTw=(hA*(T-Tw)+Gwa*(TAMB-Tw))/Cw
        else:
            Q=hA*(TAMB-T); dTw=0.0
        dm=mdot_in+ev_in-mout
        dT=(mdot_in*(cp*Tin-cv*T)+ev_in*(cp*T-cv*T)-mout*R*T+Q)/(m*cv)
        m+=dm*dt; T+=dT*dt; Tw+=dTw*dt
        p=m*R*T/V
        tgt=a.oil_hot if loaded else a.oil_cold
        theta+=(tgt-theta)*dt/a.oil_tau
        t+=dt
    if events:
        import itertools
        for c,g in itertools.groupby(events,key=lambda e:e[0]):
            g=list(g); print('EVENT cycle',c,'t',g[0][1],'-',g[-1][1],'since unload',round(g[0][1]-cycle_starts[c]),file=sys.stderr)
    return rows
def write(a,rows):
    rnd=random.Random(a.seed+1000)
    t0=datetime.datetime(2020,2,1,0,0,0)
    out=open(a.out,'w')
    out.write("Unnamed: 0,timestamp,TP2,TP3,H1,DV_pressure,Reservoirs,Oil_temperature,Motor_current,COMP,DV_eletric,Towers,MPG,LPS,Pressure_switch,Oil_level,Caudal_impulses\n")
    for i,(tj,pg,theta,loaded) in enumerate(rows):
        y=pg+rnd.gauss(0,a.noise)+a.offset
        if a.quant>0: y=round(y/a.quant)*a.quant
        comp=0.0 if loaded else 1.0
        ts=(t0+datetime.timedelta(seconds=tj)).strftime("%Y-%m-%d %H:%M:%S")
        tp2=y-0.02 if loaded else -0.012
        mc=4.0+rnd.gauss(0,0.05) if loaded else 0.04
        oil=theta+rnd.gauss(0,0.05)
        out.write(f"{i*10},{ts},{tp2:.4f},{y:.4f},{y-0.016:.4f},-0.022,{y:.4f},{oil:.3f},{mc:.3f},{comp:.1f},{1-comp:.1f},1.0,1.0,0.0,1.0,1.0,1.0\n")
    out.close()
if __name__=="__main__":
    P=argparse.ArgumentParser()
    A=P.add_argument
    A('--seed',type=int,default=1); A('--out',required=True)
    A('--V',type=float,default=0.5); A('--dt',type=float,default=0.5)
    A('--flow',type=float,default=10.0); A('--cons',type=float,default=0.8,help='g/s at 10 bar g')
    A('--tau_h',type=float,default=30.0); A('--wall_ratio',type=float,default=0.0); A('--wall_cool',type=float,default=1000.)
    A('--p_lo',type=float,default=8.0); A('--p_hi',type=float,default=10.0)
    A('--oil_hot',type=float,default=80.); A('--oil_cold',type=float,default=50.); A('--oil_tau',type=float,default=400.)
    A('--oil_phys_const',type=float,default=0.0); A('--tau_const',type=int,default=0)
    A('--T0off',type=float,default=0.0)
    A('--duration',type=float,default=10000.); A('--row_dt',type=float,default=10.); A('--rowvar',type=int,default=1)
    A('--jitter',type=int,default=0)
    A('--noise',type=float,default=0.0012); A('--quant',type=float,default=0.0); A('--offset',type=float,default=0.0)
    A('--p2',type=int,default=0); A('--thresh',type=float,default=9.0); A('--thresh_cons',type=float,default=0.0)
    A('--step_leak',type=float,default=0.0); A('--step_at',type=float,default=0.5); A('--laminar',type=float,default=0.0)
    A('--heat_derate',type=float,default=0.0)
    A('--event_cycle',type=int,default=-1); A('--event_at',type=float,default=600.); A('--event_dur',type=float,default=60.)
    A('--event_g',type=float,default=40.); A('--event_back',type=int,default=0); A('--back_gap',type=float,default=120.)
    a=P.parse_args()
    rows=sim(a); write(a,rows)
    # summary
    comp=[r[3] for r in rows]; sw=sum(1 for i in range(1,len(comp)) if comp[i]!=comp[i-1])
    print(a.out, len(rows), 'rows', sw, 'switches', 'pmin %.2f pmax %.2f'%(min(r[1] for r in rows),max(r[1] for r in rows)))
