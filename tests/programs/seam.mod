MODULE SeamModule
    !***********************************************************
    !
    ! Module:  SeamModule
    !
    ! Description:
    !   A fillet seam on the fixture, welded with a 180 mm torch.
    !   Exported from RobotStudio.
    !
    !***********************************************************
    PERS tooldata tTorch:=[TRUE,[[0,0,180],[1,0,0,0]],[3.5,[0,0,90],[1,0,0,0],0,0,0]];
    TASK PERS wobjdata wFixture:=[FALSE,TRUE,"",[[1600,250,750],[0.965925826,0,0,0.258819045]],[[0,0,0],[1,0,0,0]]];
    PERS seamdata seam1:=[0.5,0.5,[5,0,24,120,0,0,0,0,0],0.5,1,10,0,5,[5,0,24,120,0,0,0,0,0],0,1,[5,0,24,120,0,0,0,0,0],0,0,[0,0,0,0,0,0,0,0,0],0];
    PERS welddata weld1:=[6,0,[5,0,24,120,0,0,0,0,0],[0,0,0,0,0,0,0,0,0]];
    VAR triggdata gunon;
    CONST robtarget pApproach:=[[249.19,-28.40,500.00],[0.683012702,0.183012702,0.683012702,-0.183012702],[0,0,-1,1],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    CONST robtarget pSeamStart:=[[317.49,-10.10,400.00],[0.683012702,0.183012702,0.683012702,-0.183012702],[0,0,-1,1],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    CONST robtarget pSeam{3}:=[[[370.79,-17.78,400.00],[0.683012702,0.183012702,0.683012702,-0.183012702],[0,0,-1,1],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],[[424.09,-25.46,400.00],[0.683012702,0.183012702,0.683012702,-0.183012702],[0,0,-1,1],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],[[477.39,-33.13,400.00],[0.683012702,0.183012702,0.683012702,-0.183012702],[0,0,-1,1],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]]];
    CONST robtarget pSeamEnd:=[[530.69,-40.81,400.00],[0.683012702,0.183012702,0.683012702,-0.183012702],[0,0,-1,1],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    CONST robtarget pTrigg:=[[547.39,88.11,450.00],[0.683012702,0.183012702,0.683012702,-0.183012702],[0,0,-1,1],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    CONST robtarget pDO:=[[442.49,206.41,500.00],[0.683012702,0.183012702,0.683012702,-0.183012702],[0,0,-1,1],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    CONST robtarget pSync:=[[305.88,169.81,550.00],[0.683012702,0.183012702,0.683012702,-0.183012702],[0,0,-1,1],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    CONST robtarget pSearchEnd:=[[410.79,51.51,250.00],[0.683012702,0.183012702,0.683012702,-0.183012702],[0,0,-1,1],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    CONST robtarget pOffsOnly:=[[354.09,-146.70,350.00],[0.683012702,0.183012702,0.683012702,-0.183012702],[0,0,-1,1],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    CONST robtarget pTrack:=[[267.49,-96.70,450.00],[0.683012702,0.183012702,0.683012702,-0.183012702],[0,0,-1,1],[1200,9E+09,9E+09,9E+09,9E+09,9E+09]];
    CONST robtarget pSpot:=[[300.00,-50.00,420.00],[0.683012702,0.183012702,0.683012702,-0.183012702],[0,0,-1,1],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    VAR robtarget pFound;
    VAR num i;

    PROC main()
        MoveJ pApproach,v1000,z50,tTorch\WObj:=wFixture;
        ArcLStart pSeamStart,v100,seam1,weld1,fine,tTorch\WObj:=wFixture;
        ArcL pSeam{1},v100,seam1,weld1,z1,tTorch\WObj:=wFixture;
        FOR i FROM 2 TO 3 DO
            ArcL pSeam{i},v100,seam1,weld1,z1,tTorch\WObj:=wFixture;
        ENDFOR
        ArcLEnd pSeamEnd,v100,seam1,weld1,fine,tTorch\WObj:=wFixture;
        TriggIO gunon,0\DOp:=doGun,1;
        TriggL pTrigg,v500,gunon,z10,tTorch\WObj:=wFixture;
        MoveLDO pDO,v500,fine,tTorch\WObj:=wFixture,doClamp,1;
        MoveJSync pSync,v500,z10,tTorch\WObj:=wFixture,"ToolChange";
        SearchL\Stop,diTouch,pFound,pSearchEnd,v50,tTorch\WObj:=wFixture;
        MoveL pFound,v50,fine,tTorch\WObj:=wFixture;
        MoveL Offs(pOffsOnly,0,0,50),v200,fine,tTorch\WObj:=wFixture;
        MoveL RelTool(pSeamEnd,0,0,-30),v200,z10,tTorch\WObj:=wFixture;
        MoveL pTrack,v500,fine,tTorch\WObj:=wFixture;
        SpotL pSpot,vmax,gun1,tTorch\WObj:=wFixture;
    ENDPROC
ENDMODULE
